// SPDX-License-Identifier: MIT
// Time to render one 640x480 synthetic frame (ray cast + sensor model), per named scene.
#include <benchmark/benchmark.h>

#include <opencv2/imgproc.hpp>

#include "telex/common/synthetic.h"

namespace {

void BM_Render(benchmark::State& state, const char* name, bool ideal) {
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
BENCHMARK_CAPTURE(BM_Render, plane, "plane", false)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Render, box, "box", false)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Render, desk, "desk", false)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Render, moving, "moving", false)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Render, moving_ideal, "moving", true)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
