// SPDX-License-Identifier: MIT
// The stereo view (issue 12's goal: one 640x480 pair, both eyes, rendered headless in at most
// 8 ms median on this 2-core machine with Mesa's llvmpipe; issue 29's: a 1280x720 pair): background
// image, remote depth, the fingertips' contact shadows and both smooth arms and hands per eye,
// read back to BGR.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <ctime>
#include <glm/gtc/matrix_transform.hpp>
#include <memory>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <span>

#include "reaching_pose.h"
#include "telex/local/view/fig7_view.h"
#include "telex/local/view/stereo_renderer.h"
#include "telex/local/view/stereo_view.h"
#include "telex/local/view/warp.h"

namespace telex::local {
namespace {

// This thread's CPU time: with LP_NUM_THREADS=0 llvmpipe draws on the calling thread, and both
// the warp and the renderer end in a read-back (a finish), so a stage's work is all inside it.
double thread_cpu_ms() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) * 1e3 + static_cast<double>(t.tv_nsec) * 1e-6;
}

// The pixels the body covers in both eyes' body targets: each eye drawn once over a plain green
// picture with no depth (nothing hides the body), the pixels that are not green counted, over
// the divisor squared for a target of a reduced size. 0 with no body.
double body_target_px(StereoRenderer& r, EyeView right, EyeView left,
                      std::span<const Capsule> capsules, int divisor) {
  if (capsules.empty()) return 0.0;
  double covered = 0.0;
  for (EyeView* view : {&right, &left}) {
    view->background = cv::Mat3b(view->k.height, view->k.width, cv::Vec3b(0, 255, 0));
    view->depth_mm = cv::Mat1w();
    view->fingertips.clear();
    const cv::Mat3b out = r.render(*view, capsules);
    cv::Mat1b green;
    cv::inRange(out, cv::Scalar(0, 250, 0), cv::Scalar(5, 255, 5), green);
    covered += static_cast<double>(out.total() - static_cast<std::size_t>(cv::countNonZero(green)));
  }
  return covered / (divisor * divisor);
}

// One pair at `width` x `height` (the depth and image at that size): background upload, depth
// upload, contact shadows of the ten fingertips, both smooth arms and hands, readback.
// `body_divisor`: StereoRenderer::set_body_divisor's (0: by the eye's width); -1: no body at all
// (what the eye costs besides it), the fingertips' shadows kept.
// `warp_merge_cells` > 0: each eye's video and depth first reprojected by DepthWarp (a 1 degree
// turn) with that WarpOptions::merge_cells, in the renderer's context, as StereoView does with
// both head poses. `shape`: the body as triangles (shipped) or ray-marched (the renderer before
// issue 43, which stays as the reference): both in one process, so their ratio is this machine's.
void stereo_pair(benchmark::State& state, int width, int height, int body_divisor = 0,
                 int warp_merge_cells = 0, BodyShape shape = BodyShape::Mesh) {
  const bool warp = warp_merge_cells > 0;
  StereoRenderer r(width, height);
  r.set_body_divisor(std::max(body_divisor, 0));
  r.set_body_shape(shape);
  std::array<std::unique_ptr<DepthWarp>, 2> warps;
  if (warp)
    for (auto& w : warps)
      w = std::make_unique<DepthWarp>(
          width, height, WarpOptions{.merge_cells = warp_merge_cells, .read_back_bgr = false});
  const glm::dmat3 R_DisplayCapture(
      glm::rotate(glm::dmat4(1.0), 1.0 * 3.14159265358979323846 / 180.0, {0.0, 1.0, 0.0}));
  const BodyState body = reaching_body();
  auto capsules = body_capsules(body, [](const glm::dvec3& p) { return p; });
  EyeView right, left;
  right.k = left.k = kinect_v1_intrinsics(640, 480).scaled(width, height);
  left.p_RightEye = {-0.064, 0.0, 0.0};
  cv::Mat3b image(height, width);
  cv::randu(image, cv::Scalar::all(0), cv::Scalar::all(255));
  cv::Mat1w depth(height, width);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x)
      depth(y, x) = static_cast<std::uint16_t>(600 + (y + x / 4) * 480 / height);
  right.background = left.background = image;
  right.depth_mm = left.depth_mm = depth;
  for (const ArmState& arm : body.arms)
    for (const auto& finger : arm.hand.joints) right.fingertips.push_back(finger[3]);
  left.fingertips = right.fingertips;
  if (body_divisor < 0) capsules.clear();
  // The divisor the renderer takes when asked for 0 (StereoRenderer::set_body_divisor).
  const int divisor = body_divisor > 0           ? body_divisor
                      : shape == BodyShape::Mesh ? 1
                                                 : std::max(1, width / 640);
  const double body_px = body_target_px(r, right, left, capsules, divisor);
  // Per stage this thread's CPU time, for the counters: which of the two the time goes to.
  double warp_ms = 0.0, render_ms = 0.0;
  const auto eye = [&](EyeView view, std::size_t i) {
    const double t0 = thread_cpu_ms();
    if (warp) {
      WarpedEye w = warps[i]->warp(view.background, view.depth_mm, view.k,
                                   eye_display_from_capture(R_DisplayCapture, view.p_RightEye));
      // As StereoView: the picture handed over in GL, the captured one kept for the exposure.
      view.background_texture = w.texture;
      view.depth_mm = w.depth_mm;
    }
    const double t1 = thread_cpu_ms();
    cv::Mat3b out = r.render(view, capsules);
    warp_ms += t1 - t0;
    render_ms += thread_cpu_ms() - t1;
    return out;
  };
  for (auto _ : state) {
    const cv::Mat3b a = eye(right, 0);
    const cv::Mat3b b = eye(left, 1);
    benchmark::DoNotOptimize(a.data[0] + b.data[0]);
  }
  state.counters["capsules"] = static_cast<double>(capsules.size());
  // Thread CPU ms per pair (both eyes): the warps (upload, mesh, fill, read-back) and the
  // renderer (uploads, contact shadows, body, composite, read-back).
  const double pairs =
      static_cast<double>(std::max<benchmark::IterationCount>(state.iterations(), 1));
  state.counters["warp_cpu_ms"] = warp_ms / pairs;
  state.counters["render_cpu_ms"] = render_ms / pairs;
  // The body's fragments per body pixel of its target, over one more pair, counted: those
  // that passed the depth test (the mesh shades only these) and the shader's runs as llvmpipe
  // counts them (every lane of a 4x4 block a triangle or tile touches).
  if (body_px > 0.0) {
    r.set_count_body_fragments(true);
    double passed = 0.0, invocations = 0.0;
    for (std::size_t i = 0; i < 2; ++i) {
      const EyeView& view = i == 0 ? right : left;
      benchmark::DoNotOptimize(r.render(view, capsules).data);
      passed += static_cast<double>(r.body_fragments().passed);
      invocations += static_cast<double>(r.body_fragments().invocations);
    }
    r.set_count_body_fragments(false);
    state.counters["body_passed_per_px"] = passed / body_px;
    state.counters["body_fs_runs_per_px"] = invocations / body_px;
  }
}

// The argument: 0 the body as triangles, 1 ray-marched (the renderer before issue 43).
BodyShape shape_arg(std::int64_t a) { return a == 0 ? BodyShape::Mesh : BodyShape::Marched; }

void BM_StereoPair640x480(benchmark::State& state) {
  stereo_pair(state, 640, 480, 0, 0, shape_arg(state.range(0)));
}
BENCHMARK(BM_StereoPair640x480)
    ->ArgName("marched")
    ->Arg(0)
    ->Arg(1)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
// The issue 29 goal: a 1280x720 pair (render + warp <= 16 ms on llvmpipe). The arguments: the
// body's resolution divisor (0 the renderer's own: the mesh's 1, the march's 2 here; -1 no body)
// and the shape (0 triangles, 1 ray-marched).
void BM_StereoPair1280x720(benchmark::State& state) {
  stereo_pair(state, 1280, 720, static_cast<int>(state.range(0)), 0, shape_arg(state.range(1)));
}
BENCHMARK(BM_StereoPair1280x720)
    ->ArgNames({"body_divisor", "marched"})
    ->Args({0, 0})
    ->Args({0, 1})
    ->Args({2, 0})
    ->Args({-1, 0})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// The goal's whole figure: both eyes warped, then rendered with the body. Arguments: the body's
// divisor (as above), the warp's merge_cells and the shape (as above).
void BM_StereoPairWarped1280x720(benchmark::State& state) {
  stereo_pair(state, 1280, 720, static_cast<int>(state.range(0)), static_cast<int>(state.range(1)),
              shape_arg(state.range(2)));
}
BENCHMARK(BM_StereoPairWarped1280x720)
    ->ArgNames({"body_divisor", "merge", "marched"})
    ->Args({0, 4, 0})
    ->Args({0, 4, 1})
    ->Args({-1, 4, 0})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// Fig. 7's own normal map (the view thread's work when the haptic path builds only fingertip
// windows) and its composition at 1280x720 eyes.
void BM_Fig7NormalMapAndLayout(benchmark::State& state) {
  const Intrinsics k = kinect_v1_intrinsics(640, 480);
  cv::Mat1w depth(480, 640);
  for (int y = 0; y < 480; ++y)
    for (int x = 0; x < 640; ++x) depth(y, x) = static_cast<std::uint16_t>(700 + y + x / 4);
  const Intrinsics k_eye = eye_intrinsics(k, {1280, 720});
  const cv::Mat3b interaction(720, 1280, cv::Vec3b(90, 90, 90));
  std::array<FingertipForce, kFingerCount> forces{};
  forces[1].contact = true;
  forces[1].p_ModelProxy = {0.0, 0.0, 0.9};
  forces[1].force_N = {0.3, 0.0, -1.5};
  for (auto _ : state) {
    const cv::Mat3f normals = display_normals(depth, k);
    const cv::Mat3b fig7 = fig7_layout(interaction, k_eye, normals, k, forces, 0.02);
    benchmark::DoNotOptimize(fig7.data[0]);
  }
}
BENCHMARK(BM_Fig7NormalMapAndLayout)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace telex::local

BENCHMARK_MAIN();
