// SPDX-License-Identifier: MIT
// Time to render one 640x480 synthetic frame (ray cast + sensor model), per named scene.
#include <benchmark/benchmark.h>

#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

#include "telex/common/synthetic.h"

namespace {

// threads == 1 forces OpenCV's pool off, so the CPU column is the whole cost of a frame.
void BM_Render(benchmark::State& state, const char* name, bool ideal, int threads) {
  const int saved_threads = cv::getNumThreads();
  if (threads > 0) cv::setNumThreads(threads);
  const telex::synth::Scene scene = telex::synth::Scene::named(name);
  const telex::Intrinsics k = telex::kinect_v1_intrinsics();
  const telex::synth::SensorModel sensor =
      ideal ? telex::synth::SensorModel::ideal() : telex::synth::SensorModel{};
  std::uint64_t frame = 0;
  for (auto _ : state) {
    auto r = telex::synth::render(scene.at_time(frame / 30.0), k, sensor, frame);
    benchmark::DoNotOptimize(r.depth.depth_mm.data);
    ++frame;
  }
  cv::setNumThreads(saved_threads);
}

// The incremental renderer on the animated default scene: only the ball and its shadow are cast
// again each frame.
void BM_RendererMoving(benchmark::State& state) {
  cv::setNumThreads(1);
  const telex::synth::Scene scene = telex::synth::Scene::named("moving");
  telex::synth::Renderer renderer(telex::kinect_v1_intrinsics(), telex::synth::SensorModel{});
  std::uint64_t frame = 0;
  std::size_t recast = 0;
  for (auto _ : state) {
    auto r = renderer.render(scene.at_time(frame / 30.0), frame);
    benchmark::DoNotOptimize(r.depth.depth_mm.data);
    if (frame > 0) recast += renderer.last_recast_pixels();
    ++frame;
  }
  state.counters["recast_px"] = frame > 1 ? static_cast<double>(recast) / (frame - 1) : 0.0;
  cv::setNumThreads(-1);
}

// The incremental renderer on a static scene, as the synthetic depth source uses it: after the
// first frame only the sensor pass runs.
void BM_RendererStatic(benchmark::State& state, const char* name) {
  cv::setNumThreads(1);
  const telex::synth::Scene scene = telex::synth::Scene::named(name);
  telex::synth::Renderer renderer(telex::kinect_v1_intrinsics(), telex::synth::SensorModel{});
  std::uint64_t frame = 0;
  for (auto _ : state) {
    auto r = renderer.render(scene, frame++);
    benchmark::DoNotOptimize(r.depth.depth_mm.data);
  }
  cv::setNumThreads(-1);
}

// A yardstick for how loaded the machine is: REFERENCES.md quotes about 0.6 ms for this on an
// idle core, so render times scale by (this measurement / 0.6 ms) to an idle machine.
void BM_MedianBlurYardstick(benchmark::State& state) {
  cv::Mat1w depth(480, 640);
  cv::randu(depth, 0, 4000);
  cv::Mat out;
  for (auto _ : state) {
    cv::medianBlur(depth, out, 5);
    benchmark::DoNotOptimize(out.data);
  }
}

BENCHMARK(BM_MedianBlurYardstick)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_RendererMoving)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_RendererStatic, plane_1thread, "plane")->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Render, plane_1thread, "plane", false, 1)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Render, box_1thread, "box", false, 1)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Render, desk_1thread, "desk", false, 1)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Render, moving_1thread, "moving", false, 1)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Render, moving_pool, "moving", false, 0)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK_CAPTURE(BM_Render, moving_ideal_1thread, "moving", true, 1)
    ->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
