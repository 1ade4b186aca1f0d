// SPDX-License-Identifier: MIT
// Google Benchmark of the depth codecs and message framing on a rendered desk scene at 640x480.
#include <benchmark/benchmark.h>

#include "telex/common/synthetic.h"
#include "telex/proto/depth_codec.h"
#include "telex/proto/fragment.h"
#include "telex/proto/parser.h"

namespace {

using namespace telex;

const cv::Mat1w& desk_frame() {
  static const cv::Mat1w frame =
      synth::render(synth::Scene::named("desk"), kinect_v1_intrinsics(), synth::SensorModel{}, 0)
          .depth.depth_mm;
  return frame;
}

void BM_Encode(benchmark::State& state, proto::Codec codec) {
  const cv::Mat1w& f = desk_frame();
  std::size_t bytes = 0;
  for (auto _ : state) {
    auto out = proto::encode_depth(f, codec);
    bytes = out.size();
    benchmark::DoNotOptimize(out.data());
  }
  state.counters["ratio"] = static_cast<double>(f.total() * 2) / static_cast<double>(bytes);
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * f.total() * 2));
}

void BM_Decode(benchmark::State& state, proto::Codec codec) {
  const cv::Mat1w& f = desk_frame();
  const auto bytes = proto::encode_depth(f, codec);
  cv::Mat1w out;
  for (auto _ : state) {
    if (proto::decode_depth(bytes, f.cols, f.rows, codec, out) != proto::DecodeStatus::Ok)
      state.SkipWithError("decode failed");
    benchmark::DoNotOptimize(out.data);
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * f.total() * 2));
}

void BM_RvlRefEncode(benchmark::State& state) {
  const cv::Mat1w& f = desk_frame();
  std::size_t bytes = 0;
  for (auto _ : state) {
    auto out = proto::rvl_ref_encode(f);
    bytes = out.size();
    benchmark::DoNotOptimize(out.data());
  }
  state.counters["ratio"] = static_cast<double>(f.total() * 2) / static_cast<double>(bytes);
}

void BM_EncodeTiles(benchmark::State& state, proto::Codec codec) {
  const cv::Mat1w& f = desk_frame();
  const proto::TileGrid grid{f.cols, f.rows, 80, 60};
  for (auto _ : state) benchmark::DoNotOptimize(proto::encode_tiles(f, grid, codec).data());
}

// One frame's tiles as messages: encode, fragment, reassemble, parse (the UDP receive path).
void BM_TileMessagesOverUdp(benchmark::State& state) {
  const cv::Mat1w& f = desk_frame();
  const proto::TileGrid grid{f.cols, f.rows, 80, 60};
  std::vector<std::vector<std::uint8_t>> datagrams;
  std::uint32_t id = 0;
  for (const auto& t : proto::encode_tiles(f, grid, proto::Codec::Zip)) {
    const auto msg = proto::encode(proto::Header{}, proto::tile_message(t, proto::Codec::Zip));
    for (auto& d : proto::fragment_message(msg, id++, 1)) datagrams.push_back(std::move(d));
  }
  std::uint64_t now = 0;
  for (auto _ : state) {
    proto::Reassembler r;
    proto::DatagramParser p;
    int ok = 0;
    for (const auto& d : datagrams)
      if (auto m = r.push(d, ++now)) ok += p.parse(*m).ok();
    if (ok != grid.count()) state.SkipWithError("lost a tile");
  }
}

BENCHMARK_CAPTURE(BM_Encode, zip, proto::Codec::Zip)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Encode, fast, proto::Codec::Fast)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Encode, raw, proto::Codec::Raw)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Decode, zip, proto::Codec::Zip)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_Decode, fast, proto::Codec::Fast)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_RvlRefEncode)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_EncodeTiles, zip_80x60, proto::Codec::Zip)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_EncodeTiles, fast_80x60, proto::Codec::Fast)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_TileMessagesOverUdp)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
