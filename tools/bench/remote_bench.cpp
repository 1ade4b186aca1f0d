// SPDX-License-Identifier: MIT
// Remote pipeline stage costs per 640x480 frame: register, fill, stabilise, tile selection,
// encode, whole frame.
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <filesystem>

#include "telex/common/depth_io.h"
#include "telex/common/hole_fill.h"
#include "telex/common/synthetic.h"
#include "telex/common/temporal_fill.h"
#include "telex/proto/depth_codec.h"
#include "telex/remote/pipeline.h"

namespace {

using namespace telex;

// Frame 0 (and its successor) of the noisy synthetic desk, or the real desk frames when
// TELEX_SHARED_DIR points at the shared data (set it to ../shared to measure those).
struct Frames {
  cv::Mat1w a, b;
  std::string name;
};

const Frames& frames() {
  static const Frames f = [] {
    Frames out;
    if (const char* dir = std::getenv("TELEX_SHARED_DIR")) {
      const std::filesystem::path desk = std::filesystem::path(dir) / "data/real/desk";
      if (std::filesystem::exists(desk / "desk_0_depth_mm.png")) {
        out.a = load_depth(desk / "desk_0_depth_mm.png", DepthUnits::Millimetres).depth_mm;
        out.b = load_depth(desk / "desk_1_depth_mm.png", DepthUnits::Millimetres).depth_mm;
        out.name = "real desk";
        return out;
      }
    }
    const auto scene = synth::Scene::named("desk");
    out.a = synth::render(scene, kinect_v1_intrinsics(), synth::SensorModel{}, 0).depth.depth_mm;
    out.b = synth::render(scene, kinect_v1_intrinsics(), synth::SensorModel{}, 1).depth.depth_mm;
    out.name = "synthetic desk";
    return out;
  }();
  return f;
}

remote::DepthFrame frame_of(const cv::Mat1w& d, std::uint64_t id) {
  remote::DepthFrame f;
  f.image.depth_mm = d;
  f.image.intrinsics = kinect_v1_intrinsics();
  f.frame_id = id;
  f.capture_ns = static_cast<std::int64_t>(id) * 33'333'333;
  return f;
}

// A 580 px focal right eye 2.5 cm to the right of the depth camera (the default extrinsics).
remote::RegistrationConfig eye_registration(remote::RegisterMode mode) {
  remote::RegistrationConfig r;
  r.mode = mode;
  r.eye = Intrinsics{580.0, 580.0, 322.0, 236.0, 640, 480};
  return r;
}

// The registration stage alone, into a 580 px focal right eye 2.5 cm to the right (the default
// extrinsics), as FramePipeline::register_frame runs it. Arg: 0 none, 1 shift, 2 full.
void BM_Register(benchmark::State& state) {
  const auto mode = static_cast<remote::RegisterMode>(state.range(0));
  remote::PipelineConfig c;
  c.registration = eye_registration(mode);
  remote::FramePipeline p(c);
  DepthImage in;
  in.depth_mm = frames().a;
  in.intrinsics = kinect_v1_intrinsics();
  for (auto _ : state) {
    const DepthImage& out = p.register_frame(in);
    benchmark::DoNotOptimize(out.depth_mm.data);
  }
  state.SetLabel(std::string(remote::register_mode_name(mode)) + ", " + frames().name);
}
BENCHMARK(BM_Register)->Arg(0)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond);

void BM_FillMode(benchmark::State& state) {
  cv::Mat1w out;
  std::size_t holes = 0;
  for (auto _ : state) {
    auto r = fill_holes_mode_into(frames().a, out, HoleFillOptions{});
    holes = r.holes_in;
    benchmark::DoNotOptimize(out.data);
  }
  state.counters["holes_in"] = static_cast<double>(holes);
  state.SetLabel(frames().name);
}
BENCHMARK(BM_FillMode)->Unit(benchmark::kMillisecond);

void BM_FillTemporal(benchmark::State& state) {
  TemporalFill t;
  cv::Mat1w out;
  double time_ms = 0;
  for (auto _ : state) {
    t.apply((static_cast<int>(time_ms) / 33) % 2 ? frames().a : frames().b, time_ms, out);
    time_ms += 33.3;
    benchmark::DoNotOptimize(out.data);
  }
  state.SetLabel(frames().name);
}
BENCHMARK(BM_FillTemporal)->Unit(benchmark::kMillisecond);

void BM_Stabilise(benchmark::State& state) {
  Stabiliser s(static_cast<double>(state.range(0)));
  cv::Mat1w out;
  bool flip = false;
  for (auto _ : state) {
    s.apply(flip ? frames().a : frames().b, out);
    flip = !flip;
    benchmark::DoNotOptimize(out.data);
  }
}
BENCHMARK(BM_Stabilise)->Arg(0)->Arg(5)->Unit(benchmark::kMillisecond);

void BM_EncodeAllTiles(benchmark::State& state) {
  const auto codec = static_cast<proto::Codec>(state.range(0));
  const proto::TileGrid grid{640, 480, 80, 60};
  std::size_t bytes = 0;
  for (auto _ : state) {
    auto tiles = proto::encode_tiles(frames().a, grid, codec);
    bytes = 0;
    for (const auto& t : tiles) bytes += t.bytes.size();
    benchmark::DoNotOptimize(tiles.data());
  }
  state.counters["bytes"] = static_cast<double>(bytes);
  state.counters["ratio"] = 640.0 * 480.0 * 2.0 / static_cast<double>(bytes);
  state.SetLabel(std::string(proto::codec_name(codec)) + ", " + frames().name);
}
BENCHMARK(BM_EncodeAllTiles)
    ->Arg(static_cast<int>(proto::Codec::Zip))
    ->Arg(static_cast<int>(proto::Codec::Fast))
    ->Unit(benchmark::kMillisecond);

// Whole frames through the pipeline; stage times are the pipeline's own timers, averaged.
void run_pipeline(benchmark::State& state, bool key_every_frame, double k,
                  remote::RegisterMode reg = remote::RegisterMode::None) {
  remote::PipelineConfig c;
  c.registration = eye_registration(reg);
  c.key_frame_every = key_every_frame ? 1 : 100000;
  c.stabilise_k_sigma = k;
  remote::FramePipeline p(c);
  remote::StageTimes sum;
  std::size_t tiles = 0, bytes = 0;
  std::uint64_t id = 0;
  for (auto _ : state) {
    ++id;
    auto out = p.process(frame_of(id % 2 ? frames().a : frames().b, id), {});
    sum.register_ms += out.times.register_ms;
    sum.fill_ms += out.times.fill_ms;
    sum.stabilise_ms += out.times.stabilise_ms;
    sum.tile_ms += out.times.tile_ms;
    sum.encode_ms += out.times.encode_ms;
    tiles += out.tiles.size();
    for (const auto& t : out.tiles) bytes += t.bytes.size();
  }
  const double n = static_cast<double>(state.iterations());
  state.counters["reg_ms"] = sum.register_ms / n;
  state.counters["fill_ms"] = sum.fill_ms / n;
  state.counters["stab_ms"] = sum.stabilise_ms / n;
  state.counters["tile_ms"] = sum.tile_ms / n;
  state.counters["enc_ms"] = sum.encode_ms / n;
  state.counters["tiles"] = static_cast<double>(tiles) / n;
  state.counters["bytes"] = static_cast<double>(bytes) / n;
  state.SetLabel(frames().name);
}

void BM_PipelineKeyFrames(benchmark::State& state) { run_pipeline(state, true, 0.0); }
BENCHMARK(BM_PipelineKeyFrames)->Unit(benchmark::kMillisecond);
void BM_PipelineDeltaNoStabiliser(benchmark::State& state) { run_pipeline(state, false, 0.0); }
BENCHMARK(BM_PipelineDeltaNoStabiliser)->Unit(benchmark::kMillisecond);
void BM_PipelineDeltaStabilised5(benchmark::State& state) { run_pipeline(state, false, 5.0); }
BENCHMARK(BM_PipelineDeltaStabilised5)->Unit(benchmark::kMillisecond);
void BM_PipelineKeyFramesRegisterShift(benchmark::State& state) {
  run_pipeline(state, true, 0.0, remote::RegisterMode::Shift);
}
BENCHMARK(BM_PipelineKeyFramesRegisterShift)->Unit(benchmark::kMillisecond);
void BM_PipelineKeyFramesRegisterFull(benchmark::State& state) {
  run_pipeline(state, true, 0.0, remote::RegisterMode::Full);
}
BENCHMARK(BM_PipelineKeyFramesRegisterFull)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
