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
#include <opencv2/imgproc.hpp>

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

// Both arms reaching toward the camera's view, in the right eye's frame (x right, y down, z
// forward): shoulders above and behind the eyes.
BodyState reaching_body() {
  Body body;
  BodyInputs in;
  in.time_ns = 0;
  for (Side s : kSides) {
    const std::size_t i = index_of(s);
    const double x = s == Side::Right ? 0.18 : -0.18;
    // World = the right eye's camera frame here, with up = -y.
    in.shoulder[i] = Pose{{x, 0.25, -0.05}, {1.0, 0.0, 0.0, 0.0}};
    in.wrist[i] = Pose{{x * 0.6, 0.15, 0.45}, {1.0, 0.0, 0.0, 0.0}};
    in.bend[i] = {0.3, 0.2, 0.4, 0.6, 0.7};
  }
  BodyDims dims;
  dims.up_world = {0.0, -1.0, 0.0};
  dims.forearm_axis_from_wrist = false;
  Body b(dims);
  return b.update(in);
}

// One pair at `width` x `height` (the depth and image at that size): background upload, depth
// upload, contact shadows of the ten fingertips, both smooth arms and hands, readback.
// `body_divisor`: StereoRenderer::set_body_divisor's (0: by the eye's width); -1: no body at all
// (what the eye costs besides it), the fingertips' shadows kept.
// `warp_merge_cells` > 0: each eye's video and depth first reprojected by DepthWarp (a 1 degree
// turn) with that WarpOptions::merge_cells, in the renderer's context, as StereoView does with
// both head poses.
void stereo_pair(benchmark::State& state, int width, int height, int body_divisor = 0,
                 int warp_merge_cells = 0) {
  const bool warp = warp_merge_cells > 0;
  StereoRenderer r(width, height);
  r.set_body_divisor(std::max(body_divisor, 0));
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
}

void BM_StereoPair640x480(benchmark::State& state) { stereo_pair(state, 640, 480); }
BENCHMARK(BM_StereoPair640x480)->Unit(benchmark::kMillisecond)->UseRealTime();
// The issue 29 goal: a 1280x720 pair (render + warp <= 16 ms on llvmpipe). The argument is the
// body's resolution divisor: 0 by the eye's width (2 here), 1 the full 1280x720; -1 no body.
void BM_StereoPair1280x720(benchmark::State& state) {
  stereo_pair(state, 1280, 720, static_cast<int>(state.range(0)));
}
BENCHMARK(BM_StereoPair1280x720)
    ->ArgName("body_divisor")
    ->Arg(0)
    ->Arg(1)
    ->Arg(4)
    ->Arg(-1)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// The goal's whole figure: both eyes warped, then rendered with the body. Arguments: the body's
// divisor (as above) and the warp's merge_cells; 1, 1 is the pipeline before both levers.
void BM_StereoPairWarped1280x720(benchmark::State& state) {
  stereo_pair(state, 1280, 720, static_cast<int>(state.range(0)), static_cast<int>(state.range(1)));
}
BENCHMARK(BM_StereoPairWarped1280x720)
    ->ArgNames({"body_divisor", "merge"})
    ->Args({0, 4})
    ->Args({1, 1})
    ->Args({4, 4})
    ->Args({-1, 4})
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
