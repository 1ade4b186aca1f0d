// SPDX-License-Identifier: MIT
// libFuzzer target: a session of datagrams from a NatNet server, through every parser the
// station's client (local_node/inputs/src/natnet_client.cpp, Impl::handle) applies to them, in its
// order: the packet framing; server info (both readings: the 264 bytes, then the version's
// connection fields), which sets the layout of later frames unless the client was given one; model
// definitions; FRAMEOFDATA in that layout, then the client's checks (reported latency, the
// frame's place in the timeline, each rigid body's pose). Echo replies, unrecognized-request
// replies and message strings reach the framing only: the client reads nothing more of them.
//
// Input: byte 0 = the client's configured version (index into kVersions; 11 = none, wait for the
// server info). Then records: u16 little-endian length, u8 milliseconds since the last datagram,
// that many datagram bytes (a short last record takes what is left).
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <span>
#include <vector>

#include "telex/local/inputs/natnet_client.h"
#include "telex/natnet/natnet.h"

namespace {

namespace natnet = telex::local::natnet;
using telex::local::FrameStamp;
using Bytes = std::vector<std::uint8_t>;

constexpr natnet::Version kVersions[] = {{2, 0},  {2, 3}, {2, 5}, {2, 6}, {2, 7}, {2, 9},
                                         {2, 11}, {3, 0}, {3, 1}, {4, 0}, {4, 1}};

void check(bool ok) {
  if (!ok) std::abort();
}

// A status points inside what it was given.
void check_status(const natnet::ParseStatus& st, std::span<const std::uint8_t> in) {
  if (!st.ok()) check(st.offset <= in.size() && std::strlen(st.reason) > 0);
}

bool same_bits(float a, float b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// What the client keeps between datagrams (Impl's members of the same names).
struct Session {
  std::optional<natnet::Version> configured;
  natnet::Version version{0, 0};
  std::uint64_t clock_hz = 0;
  std::int64_t now_ns = 1'000'000'000;
  std::optional<FrameStamp> last_frame;
  natnet::Frame frame;  // reused, as the client reuses its own
  std::array<std::optional<telex::Pose>, 4> accepted{};
  std::array<FrameStamp, 4> accepted_stamp{};
};

// Impl::on_server_info: the short reading decides; the full one, when it parses, replaces it.
void on_server_info(Session& s, std::span<const std::uint8_t> payload) {
  natnet::ServerInfo si;
  const natnet::ParseStatus st = natnet::parse_server_info(payload, si);
  check_status(st, payload);
  if (!st.ok()) return;
  check(natnet::supported(si.natnet_version) && si.app_name.size() <= 256 &&
        si.app_name.find('\0') == std::string::npos &&
        si.natnet_version.major == si.natnet_version_bytes[0] &&
        si.natnet_version.minor == si.natnet_version_bytes[1]);
  if (!s.configured) s.version = si.natnet_version;
  natnet::ServerInfo full;
  const natnet::ParseStatus fst = natnet::parse_server_info(payload, si.natnet_version, full);
  check_status(fst, payload);
  if (fst.ok()) {
    const bool v3 = si.natnet_version.major >= 3;
    check(full.has_connection_info == v3 &&
          payload.size() == (v3 ? natnet::kServerInfoBytes3 : natnet::kServerInfoBytes2));
    // The simulator's writer gives back what was read (a name of 256 bytes loses its last).
    const Bytes again = natnet::make_server_info(full);
    natnet::PacketView pkt;
    natnet::ServerInfo back;
    check(natnet::parse_packet(again, pkt).ok() && pkt.message_id == natnet::kPingResponse &&
          natnet::parse_server_info(pkt.payload, full.natnet_version, back).ok());
    check(back.natnet_version == full.natnet_version && back.app_version == full.app_version &&
          back.high_res_clock_hz == full.high_res_clock_hz && back.data_port == full.data_port &&
          back.multicast == full.multicast && back.multicast_group == full.multicast_group &&
          (full.app_name.size() > 255 || back.app_name == full.app_name));
    si = full;
  }
  s.clock_hz = si.has_connection_info ? si.high_res_clock_hz : 0;
}

// MODELDEF in the session's layout (2.0 before the server said): what parses re-encodes to
// datasets that parse to the same bodies.
void on_model_defs(const Session& s, std::span<const std::uint8_t> payload) {
  const natnet::Version v = s.version.major == 0 ? natnet::Version{2, 0} : s.version;
  natnet::ModelDefs defs;
  const natnet::ParseStatus st = natnet::parse_model_defs(payload, v, defs);
  check_status(st, payload);
  if (!st.ok()) return;
  natnet::PacketView pkt;
  natnet::ModelDefs back;
  const Bytes again = natnet::make_model_defs(defs, v);
  check(natnet::parse_packet(again, pkt).ok() && pkt.message_id == natnet::kModelDef &&
        natnet::parse_model_defs(pkt.payload, v, back).ok() &&
        back.rigid_bodies.size() == defs.rigid_bodies.size());
  for (std::size_t i = 0; i < defs.rigid_bodies.size(); ++i) {
    const auto &a = defs.rigid_bodies[i], &b = back.rigid_bodies[i];
    check(a.name == b.name && a.id == b.id && a.parent_id == b.parent_id &&
          same_bits(a.offset_m.x, b.offset_m.x) && same_bits(a.offset_m.y, b.offset_m.y) &&
          same_bits(a.offset_m.z, b.offset_m.z));
    // A name is a C string on the wire.
    check(a.name.find('\0') == std::string::npos);
  }
}

// A parsed frame is what the writer writes of it: writing what parses of the written bytes gives
// those bytes again (the writer leaves out what a version does not carry, and the 4.1 assets).
void check_frame_round_trip(const natnet::Frame& f, natnet::Version v) {
  const Bytes once = natnet::encode_frame(f, v);
  natnet::PacketView pkt;
  static natnet::Frame back;
  check(natnet::parse_packet(once, pkt).ok() && pkt.message_id == natnet::kFrameOfData &&
        natnet::parse_frame(pkt.payload, v, back).ok());
  check(natnet::encode_frame(back, v) == once);
}

// What check_pose passes is finite, within range and of unit length.
void check_passed(const telex::Pose& p, const telex::local::PoseLimits& limits) {
  for (int k = 0; k < 3; ++k)
    check(std::isfinite(p.p_m[k]) && std::abs(p.p_m[k]) <= limits.max_abs_coordinate_m);
  const double norm = std::sqrt(p.q.w * p.q.w + p.q.x * p.q.x + p.q.y * p.q.y + p.q.z * p.q.z);
  check(std::abs(norm - 1.0) < 1e-9);
}

// Impl::publish for the frame's first bodies: an untracked one is checked alone and is no speed
// reference; a tracked one against its last accepted pose.
void check_bodies(Session& s, const FrameStamp& stamp) {
  const telex::local::PoseLimits limits;
  const telex::local::TimelineLimits timeline;
  using telex::local::PoseVerdict;
  for (std::size_t i = 0; i < s.accepted.size() && i < s.frame.rigid_bodies.size(); ++i) {
    const natnet::RigidBody& rb = s.frame.rigid_bodies[i];
    telex::Pose out;
    if (!rb.tracking_valid) {
      if (telex::local::check_pose(rb, limits, nullptr, 0.0, out) == PoseVerdict::Ok)
        check_passed(out, limits);
      continue;
    }
    auto& last = s.accepted[i];
    const double dt_s =
        last ? telex::local::speed_check_dt_s(s.accepted_stamp[i], stamp, timeline) : 0.0;
    check(std::isfinite(dt_s) && dt_s >= 0.0);
    if (telex::local::check_pose(rb, limits, last ? &*last : nullptr, dt_s, out) != PoseVerdict::Ok)
      continue;
    check_passed(out, limits);
    last = out;
    s.accepted_stamp[i] = stamp;
  }
}

// Impl::on_frame: nothing before the layout is known; then the frame, its latency, its place in
// the timeline, its bodies.
void on_frame(Session& s, std::span<const std::uint8_t> payload) {
  const natnet::Version v = s.version;
  if (v.major == 0) return;  // counted before_version
  const natnet::ParseStatus st = natnet::parse_frame(payload, v, s.frame);
  check_status(st, payload);
  if (!st.ok()) return;
  check_frame_round_trip(s.frame, v);
  const std::int64_t latency_ns = telex::local::natnet_reported_latency_ns(s.frame, v, s.clock_hz);
  check(latency_ns >= 0 && latency_ns <= 1'000'000'000);
  const double stamp_s =
      v.at_least(2, 6) ? s.frame.timestamp_s : static_cast<double>(s.now_ns) * 1e-9;
  if (!std::isfinite(stamp_s)) return;  // rejected_nonfinite
  const FrameStamp stamp{s.frame.frame_number, stamp_s, s.now_ns};
  if (s.last_frame) {
    const auto verdict = telex::local::check_frame(*s.last_frame, stamp, {});
    if (verdict == telex::local::FrameVerdict::Backwards ||
        verdict == telex::local::FrameVerdict::TooFarAhead)
      return;  // frame_jumps
  }
  s.last_frame = stamp;
  check_bodies(s, stamp);
}

// Impl::handle, for datagrams from the server's own endpoint.
void handle(Session& s, std::span<const std::uint8_t> datagram) {
  natnet::PacketView pkt;
  const natnet::ParseStatus st = natnet::parse_packet(datagram, pkt);
  check_status(st, datagram);
  if (!st.ok()) return;
  check(pkt.payload.data() == datagram.data() + 4 && pkt.payload.size() + 4 <= datagram.size());
  if (pkt.message_id == natnet::kPingResponse) return on_server_info(s, pkt.payload);
  if (pkt.message_id == natnet::kModelDef) return on_model_defs(s, pkt.payload);
  if (pkt.message_id == natnet::kFrameOfData) return on_frame(s, pkt.payload);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  Session s;
  if (data[0] % 12 < std::size(kVersions)) s.configured = kVersions[data[0] % 12];
  if (s.configured) s.version = *s.configured;
  std::span<const std::uint8_t> in(data + 1, size - 1);
  while (in.size() >= 3) {
    const std::size_t n = std::min<std::size_t>(in[0] | (in[1] << 8), in.size() - 3);
    s.now_ns += std::int64_t{in[2]} * 1'000'000;
    handle(s, in.subspan(3, n));
    in = in.subspan(3 + n);
  }
  return 0;
}
