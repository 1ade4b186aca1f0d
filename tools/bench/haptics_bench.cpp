// SPDX-License-Identifier: MIT
// Benchmarks of the haptic model: one fingertip update on a 640x480 surface (goal <= 5 us).
#include <benchmark/benchmark.h>

#include <cmath>
#include <glm/geometric.hpp>
#include <memory>

#include "telex/haptics/haptic_model.h"

namespace {

using namespace telex;

// A 35-degree plane at 1 m over the full Kinect frame, with its normals.
std::shared_ptr<const Surface> tilted_surface() {
  const Intrinsics k = kinect_v1_intrinsics(640, 480);
  const double a = 35.0 * M_PI / 180.0;
  const glm::dvec3 n(std::sin(a), 0.0, -std::cos(a));
  const double d = glm::dot(n, glm::dvec3(0, 0, 1.0));
  cv::Mat1f depth(k.height, k.width);
  for (int v = 0; v < k.height; ++v)
    for (int u = 0; u < k.width; ++u) {
      const glm::dvec3 ray((u - k.cx) / k.fx, (v - k.cy) / k.fy, 1.0);
      depth(v, u) = static_cast<float>(d / glm::dot(n, ray));
    }
  return std::make_shared<const Surface>(make_surface(depth, k, 0, 1));
}

// Fingertips stroking in contact (the expensive case: plane queries, friction, march, re-snap).
void BM_FingertipUpdateInContact(benchmark::State& state) {
  const int fingers = static_cast<int>(state.range(0));
  HapticParams p;
  p.startup_ramp_s = 0.0;
  p.stale_limit_s = 1e6;
  HapticModel model(p, fingers);
  const auto surface = tilted_surface();
  const double a = 35.0 * M_PI / 180.0;
  const glm::dvec3 n(std::sin(a), 0.0, -std::cos(a));
  const glm::dvec3 t = glm::normalize(glm::cross(n, glm::dvec3(0, 1, 0)));
  std::vector<FingertipInput> in(fingers);
  std::vector<FingertipForce> out(fingers);
  std::int64_t now = 0;
  std::int64_t i = 0;
  for (auto _ : state) {
    // 5 mm deep, sliding back and forth 5 cm at 0.1 m/s.
    const double s = 0.05 * std::sin(static_cast<double>(i++) * 2e-3);
    for (int f = 0; f < fingers; ++f)
      in[f].p_ModelFingertip = glm::dvec3(0.0, 0.02 * f, 1.0) + s * t - 0.005 * n;
    now += 1'000'000;
    benchmark::DoNotOptimize(model.tick(now, surface, in, out));
    benchmark::DoNotOptimize(out.data());
  }
  state.SetItemsProcessed(state.iterations() * fingers);
  // Seconds per fingertip update (shown with an SI prefix, e.g. 1.2u = 1.2 us).
  state.counters["s_per_fingertip"] = benchmark::Counter(
      fingers, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_FingertipUpdateInContact)->Arg(1)->Arg(5);

// Fingertip in free space in front of the surface (the common case between touches).
void BM_FingertipUpdateFree(benchmark::State& state) {
  HapticParams p;
  p.stale_limit_s = 1e6;
  HapticModel model(p, 1);
  const auto surface = tilted_surface();
  FingertipInput in;
  FingertipForce out;
  std::int64_t now = 0;
  std::int64_t i = 0;
  for (auto _ : state) {
    in.p_ModelFingertip = glm::dvec3(0.05 * std::sin(static_cast<double>(i++) * 2e-3), 0.0, 0.6);
    now += 1'000'000;
    benchmark::DoNotOptimize(model.tick(now, surface, std::span(&in, 1), std::span(&out, 1)));
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_FingertipUpdateFree);

// Building a snapshot from a 640x480 depth map with central-difference normals (30 Hz side).
void BM_MakeSurface640x480(benchmark::State& state) {
  const auto s = tilted_surface();
  for (auto _ : state) {
    Surface built = make_surface(s->depth_m, s->intrinsics, 0, 1);
    benchmark::DoNotOptimize(built.normals.data);
  }
}
BENCHMARK(BM_MakeSurface640x480)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
