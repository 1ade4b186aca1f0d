// SPDX-License-Identifier: MIT
// The stereo view (issue 12's goal: one 640x480 pair, both eyes, rendered headless in at most
// 8 ms median on this 2-core machine with Mesa's llvmpipe): background image, remote depth and
// both arms and hands (50 capsules) per eye, read back to BGR.
#include <benchmark/benchmark.h>

#include <cmath>
#include <opencv2/imgproc.hpp>

#include "telex/local/stereo_renderer.h"

namespace telex::local {
namespace {

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

void BM_StereoPair640x480(benchmark::State& state) {
  StereoRenderer r(640, 480);
  const auto capsules = body_capsules(reaching_body(), [](const glm::dvec3& p) { return p; });
  EyeView right, left;
  right.k = left.k = kinect_v1_intrinsics(640, 480);
  left.p_RightEye = {-0.064, 0.0, 0.0};
  cv::Mat3b image(480, 640);
  cv::randu(image, cv::Scalar::all(0), cv::Scalar::all(255));
  cv::Mat1w depth(480, 640);
  for (int y = 0; y < 480; ++y)
    for (int x = 0; x < 640; ++x) depth(y, x) = static_cast<std::uint16_t>(600 + y + x / 4);
  right.background = left.background = image;
  right.depth_mm = left.depth_mm = depth;
  for (auto _ : state) {
    const cv::Mat3b a = r.render(right, capsules);
    const cv::Mat3b b = r.render(left, capsules);
    benchmark::DoNotOptimize(a.data[0] + b.data[0]);
  }
  state.counters["capsules"] = static_cast<double>(capsules.size());
}
BENCHMARK(BM_StereoPair640x480)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace telex::local

BENCHMARK_MAIN();
