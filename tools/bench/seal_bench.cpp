// SPDX-License-Identifier: MIT
// Cost of the datagram seal (AES-256-GCM, seal.h) beside the plain path: one 1400-byte datagram
// sealed and opened, and one 640x480 key frame's tiles (64 zip tiles and the manifest) encoded,
// fragmented and sealed by the sender, opened, reassembled and decoded by the receiver. Arg 0:
// 0 = plain, 1 = sealed. After the runs, the sealed/plain ratio of each pair is printed.
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <map>

#include "telex/common/depth_io.h"
#include "telex/common/synthetic.h"
#include "telex/proto/depth_codec.h"
#include "telex/proto/fragment.h"
#include "telex/proto/parser.h"
#include "telex/proto/seal.h"

namespace {

using namespace telex;

// Frame 0 of the noisy synthetic desk, or of the real desk with TELEX_SHARED_DIR set.
const cv::Mat1w& frame() {
  static const cv::Mat1w f = [] {
    if (const char* dir = std::getenv("TELEX_SHARED_DIR")) {
      const auto p = std::filesystem::path(dir) / "data/real/desk/desk_0_depth_mm.png";
      if (std::filesystem::exists(p)) return load_depth(p, DepthUnits::Millimetres).depth_mm;
    }
    return synth::render(synth::Scene::named("desk"), kinect_v1_intrinsics(), synth::SensorModel{},
                         0)
        .depth.depth_mm;
  }();
  return f;
}

// A key frame as the server sends it: 64 zip tiles and the manifest.
std::vector<proto::Message> frame_messages() {
  const proto::TileGrid grid{640, 480, 80, 60};
  std::vector<proto::Message> msgs;
  for (const auto& t : proto::encode_tiles(frame(), grid, proto::Codec::Zip))
    msgs.push_back(proto::tile_message(t, proto::Codec::Zip));
  msgs.push_back(proto::FrameManifest{1, 64, true, {}, {}});
  return msgs;
}

proto::DirectionKey bench_key() {
  proto::DirectionKey k;
  for (std::size_t i = 0; i < k.key.size(); ++i) k.key[i] = static_cast<std::uint8_t>(i * 7 + 1);
  for (std::size_t i = 0; i < k.iv.size(); ++i) k.iv[i] = static_cast<std::uint8_t>(i * 13 + 5);
  return k;
}

// One datagram of the largest size: sealed, or (plain) copied into its own buffer as the send
// path does with every fragment.
void BM_Datagram1400Send(benchmark::State& state) {
  const bool sealed = state.range(0) != 0;
  std::vector<std::uint8_t> d(1400);
  for (std::size_t i = 0; i < d.size(); ++i) d[i] = static_cast<std::uint8_t>(i * 31);
  proto::DatagramSealer sealer(bench_key());
  for (auto _ : state) {
    std::vector<std::uint8_t> out = sealed ? sealer.seal(d) : std::vector<std::uint8_t>(d);
    benchmark::DoNotOptimize(out.data());
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations()) * 1400);
  state.SetLabel(sealed ? "sealed" : "plain");
}
BENCHMARK(BM_Datagram1400Send)->Arg(0)->Arg(1);

void BM_Datagram1400Receive(benchmark::State& state) {
  const bool sealed = state.range(0) != 0;
  std::vector<std::uint8_t> d(1400);
  for (std::size_t i = 0; i < d.size(); ++i) d[i] = static_cast<std::uint8_t>(i * 31);
  // Enough distinct sealed datagrams that the replay window never refuses one.
  proto::DatagramSealer sealer(bench_key());
  std::vector<std::vector<std::uint8_t>> wire;
  for (int i = 0; i < 1024; ++i) wire.push_back(sealer.seal(d));
  std::vector<std::uint8_t> plain;
  std::size_t ok = 0, i = 0;
  auto opener = std::make_unique<proto::DatagramOpener>(bench_key());
  for (auto _ : state) {
    if (sealed) {
      if (i == wire.size()) {
        state.PauseTiming();
        opener = std::make_unique<proto::DatagramOpener>(bench_key());
        i = 0;
        state.ResumeTiming();
      }
      ok += opener->open(wire[i++], plain) == proto::OpenError::None;
    } else {
      plain.assign(d.begin(), d.end());  // the plain receive path hands the bytes on as they are
      ++ok;
    }
    benchmark::DoNotOptimize(plain.data());
  }
  if (ok != static_cast<std::size_t>(state.iterations()))
    state.SkipWithError("a datagram did not open");
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations()) * 1400);
  state.SetLabel(sealed ? "sealed" : "plain");
}
BENCHMARK(BM_Datagram1400Receive)->Arg(0)->Arg(1);

// The sender's work for one frame over UDP: encode, fragment, and seal each datagram.
std::vector<std::vector<std::uint8_t>> send_frame(const std::vector<proto::Message>& msgs,
                                                  proto::DatagramSealer* sealer,
                                                  std::uint32_t& message_id) {
  std::vector<std::vector<std::uint8_t>> wire;
  std::uint32_t seq = 0;
  for (const auto& m : msgs) {
    proto::Header h;
    h.session_id = 3;
    h.seq = seq++;
    h.frame_id = 1;
    for (auto& d : proto::fragment_message(proto::encode(h, m), message_id++, 1))
      wire.push_back(sealer ? sealer->seal(d) : std::move(d));
  }
  return wire;
}

void BM_FrameSend(benchmark::State& state) {
  const bool sealed = state.range(0) != 0;
  const auto msgs = frame_messages();
  proto::DatagramSealer sealer(bench_key());
  std::uint32_t id = 0;
  std::size_t bytes = 0, datagrams = 0;
  for (auto _ : state) {
    auto wire = send_frame(msgs, sealed ? &sealer : nullptr, id);
    bytes = 0;
    for (const auto& w : wire) bytes += w.size();
    datagrams = wire.size();
    benchmark::DoNotOptimize(wire.data());
  }
  state.counters["wire_bytes"] = static_cast<double>(bytes);
  state.counters["datagrams"] = static_cast<double>(datagrams);
  state.SetLabel(sealed ? "sealed" : "plain");
}
BENCHMARK(BM_FrameSend)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

void BM_FrameReceive(benchmark::State& state) {
  const bool sealed = state.range(0) != 0;
  const auto msgs = frame_messages();
  proto::DatagramSealer sealer(bench_key());
  std::uint32_t id = 0;
  const auto wire = send_frame(msgs, sealed ? &sealer : nullptr, id);
  std::vector<std::uint8_t> plain;
  std::size_t ok = 0;
  for (auto _ : state) {
    // A fresh receiver per frame: its replay window would (rightly) refuse the same frame twice.
    ok = 0;
    proto::DatagramOpener opener(bench_key());
    proto::Reassembler r;
    proto::DatagramParser p;
    for (const auto& d : wire) {
      std::span<const std::uint8_t> body(d);
      if (sealed) {
        if (opener.open(d, plain) != proto::OpenError::None) continue;
        body = plain;
      }
      if (auto whole = r.push(body, 0)) ok += p.parse(*whole).ok() ? 1 : 0;
    }
    benchmark::DoNotOptimize(ok);
  }
  if (ok != msgs.size()) state.SkipWithError("not every message arrived");
  state.SetLabel(sealed ? "sealed" : "plain");
}
BENCHMARK(BM_FrameReceive)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

// Prints what the console reporter prints, then sealed/plain per benchmark from the medians
// (or the means when run without repetitions) of CPU time: on the shared machine wall time also
// counts the other processes' turns.
class RatioReporter : public benchmark::ConsoleReporter {
 public:
  void ReportRuns(const std::vector<Run>& runs) override {
    ConsoleReporter::ReportRuns(runs);
    for (const auto& r : runs) {
      const std::string name = r.benchmark_name();
      const bool median = r.aggregate_name == "median";
      if (!r.aggregate_name.empty() && !median) continue;
      const auto slash = name.find('/');
      if (slash == std::string::npos) continue;
      const std::string base = name.substr(0, slash);
      const bool sealed = name.compare(slash + 1, 1, "1") == 0;
      auto& slot = sealed ? times_[base].second : times_[base].first;
      if (median || slot == 0) slot = r.GetAdjustedCPUTime();
    }
  }
  void Finalize() override {
    ConsoleReporter::Finalize();
    for (const auto& [name, t] : times_)
      if (t.first > 0 && t.second > 0)
        std::cout << "ratio " << name << " sealed/plain (CPU time) = " << t.second / t.first
                  << "\n";
  }

 private:
  std::map<std::string, std::pair<double, double>> times_;  // plain, sealed
};

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  RatioReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  benchmark::Shutdown();
  return 0;
}
