// SPDX-License-Identifier: MIT
// The view's depth-image-based warp (issue 29: render + warp of a 2x1280x720 pair in at most
// 16 ms on llvmpipe): one eye's video and depth moved 3 degrees of yaw, uploaded, drawn (mesh and
// hole fill) and read back, per eye. The capture is a wall with boxes in front, so edges drop
// triangles and open holes as the real scene does.
#include <benchmark/benchmark.h>

#include <cmath>
#include <glm/gtc/matrix_transform.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "telex/local/view/warp.h"

namespace telex::local {
namespace {

void BM_WarpEye(benchmark::State& state) {
  const int w = static_cast<int>(state.range(0)), h = static_cast<int>(state.range(1));
  const Intrinsics k = kinect_v1_intrinsics(640, 480).scaled(w, h);
  DepthWarp warp(w, h,
                 {.grid_step_px = static_cast<int>(state.range(2)),
                  .merge_cells = static_cast<int>(state.range(3))});
  cv::Mat3b image(h, w);
  cv::randu(image, cv::Scalar::all(0), cv::Scalar::all(255));
  cv::Mat1w depth(h, w);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) depth(y, x) = static_cast<std::uint16_t>(2500 + y / 2);
  for (int i = 0; i < 4; ++i)
    depth(cv::Rect(w / 10 + i * w / 5, h / 3, w / 8, h / 2)).setTo(900 + 200 * i);
  const double a = 3.0 * 3.14159265358979323846 / 180.0;
  const glm::dmat3 R(glm::rotate(glm::dmat4(1.0), a, glm::dvec3(0.0, 1.0, 0.0)));
  const RigidTransform X = eye_display_from_capture(R, {-0.065, 0.0, 0.0});
  for (auto _ : state) {
    const WarpedEye out = warp.warp(image, depth, k, X, R);
    benchmark::DoNotOptimize(out.bgr.data[0]);
  }
  std::vector<std::uint32_t> indices;
  mesh_triangles(depth, warp.options().grid_step_px, warp.options().max_depth_step_ratio, indices,
                 warp.options().merge_cells);
  state.counters["triangles"] = static_cast<double>(indices.size() / 3);
}
BENCHMARK(BM_WarpEye)
    ->ArgNames({"w", "h", "grid_px", "merge"})
    ->Args({1280, 720, 8, 2})
    ->Args({1280, 720, 8, 4})
    ->Args({1280, 720, 8, 1})
    ->Args({1280, 720, 16, 1})
    ->Args({1280, 720, 4, 1})
    ->Args({640, 480, 8, 2})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace
}  // namespace telex::local

BENCHMARK_MAIN();
