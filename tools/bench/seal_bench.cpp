// SPDX-License-Identifier: MIT
// Cost of --psk per 640x480 frame: the sender's encode (+ tags) and fragmentation, the receiver's
// tag checks, reassembly and decode, with and without a key, over UDP and TCP framing; bytes on
// the wire per frame. Arg 0: 0 = no key, 1 = key. Arg 1: 0 = TCP framing, 1 = UDP datagrams.
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <filesystem>

#include "telex/common/depth_io.h"
#include "telex/common/synthetic.h"
#include "telex/proto/auth.h"
#include "telex/proto/depth_codec.h"
#include "telex/proto/fragment.h"
#include "telex/proto/parser.h"

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
  proto::FrameManifest fm{1, 64, true, {}, {}};
  for (const auto& t : proto::encode_tiles(frame(), grid, proto::Codec::Zip)) {
    msgs.push_back(proto::tile_message(t, proto::Codec::Zip));
  }
  msgs.push_back(fm);
  return msgs;
}

const proto::AuthKey& session_key() {
  static const proto::AuthKey k =
      proto::derive_session_key(proto::AuthKey(std::vector<std::uint8_t>(32, 0x42)), 1, 2, 3);
  return k;
}

// What goes on the wire for one frame: TCP writes or UDP datagrams.
std::vector<std::vector<std::uint8_t>> send_frame(const std::vector<proto::Message>& msgs,
                                                  bool keyed, bool udp, std::uint32_t& seq,
                                                  std::uint32_t& message_id) {
  const proto::AuthKey* key = keyed ? &session_key() : nullptr;
  std::vector<std::vector<std::uint8_t>> wire;
  for (const auto& m : msgs) {
    proto::Header h;
    h.session_id = 3;
    h.seq = seq++;
    h.frame_id = 1;
    if (!udp) {
      wire.push_back(proto::encode_stream_sealed(h, m, key));
      continue;
    }
    for (auto& d : proto::fragment_message(proto::encode_sealed(h, m, key), message_id++, 1)) {
      if (key) proto::append_tag(d, *key);
      wire.push_back(std::move(d));
    }
  }
  return wire;
}

void BM_SendFrame(benchmark::State& state) {
  const bool keyed = state.range(0) != 0, udp = state.range(1) != 0;
  const auto msgs = frame_messages();
  std::uint32_t seq = 0, id = 0;
  std::size_t bytes = 0, items = 0;
  for (auto _ : state) {
    auto wire = send_frame(msgs, keyed, udp, seq, id);
    bytes = 0;
    for (const auto& w : wire) bytes += w.size();
    items = wire.size();
    benchmark::DoNotOptimize(wire.data());
  }
  state.counters["wire_bytes"] = static_cast<double>(bytes);
  state.counters["kB_per_s_at_30Hz"] = static_cast<double>(bytes) * 30.0 / 1000.0;
  state.counters["writes_or_datagrams"] = static_cast<double>(items);
  state.SetLabel(std::string(keyed ? "psk" : "no key") + (udp ? ", udp" : ", tcp"));
}
BENCHMARK(BM_SendFrame)
    ->Args({0, 1})
    ->Args({1, 1})
    ->Args({0, 0})
    ->Args({1, 0})
    ->Unit(benchmark::kMillisecond);

void BM_ReceiveFrame(benchmark::State& state) {
  const bool keyed = state.range(0) != 0, udp = state.range(1) != 0;
  const auto msgs = frame_messages();
  std::uint32_t seq = 0, id = 0;
  const auto wire = send_frame(msgs, keyed, udp, seq, id);
  std::size_t ok = 0;
  for (auto _ : state) {
    // A fresh receiver per frame: the replay window would (rightly) reject the same frame twice.
    ok = 0;
    if (udp) {
      proto::Reassembler r;
      proto::DatagramParser p;
      if (keyed) p.set_key(session_key());
      for (const auto& d : wire) {
        std::span<const std::uint8_t> body(d);
        if (keyed) {
          const auto b = proto::verify_and_strip(d, session_key());
          if (!b) continue;
          body = *b;
        }
        if (auto whole = r.push(body, 0)) ok += p.parse(*whole).ok() ? 1 : 0;
      }
    } else {
      proto::StreamParser p;
      if (keyed) p.set_key(session_key());
      for (const auto& w : wire) {
        (void)p.feed(w);
        while (auto res = p.next()) ok += res->ok() ? 1 : 0;
      }
    }
    benchmark::DoNotOptimize(ok);
  }
  if (ok != msgs.size()) state.SkipWithError("not every message arrived");
  state.SetLabel(std::string(keyed ? "psk" : "no key") + (udp ? ", udp" : ", tcp"));
}
BENCHMARK(BM_ReceiveFrame)
    ->Args({0, 1})
    ->Args({1, 1})
    ->Args({0, 0})
    ->Args({1, 0})
    ->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
