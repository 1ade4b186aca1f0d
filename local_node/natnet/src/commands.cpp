// SPDX-License-Identifier: MIT
// NatNet command replies: server info, model definitions and echo, each in the layout of the
// NatNet version the server streams (PacketClient.cpp of SDK 2.5 .. 3.1, NatNetClient.py 4.x).
#include <algorithm>
#include <cstring>
#include <stdexcept>

#include "telex/base/byte_cursor.h"
#include "telex/natnet/natnet.h"

namespace telex::local::natnet {

namespace {

#define TELEX_NN_NEED(expr, why)                      \
  do {                                                \
    if (!(expr)) return ParseStatus{why, r.offset()}; \
  } while (0)

ParseStatus read_rigid_body_def(ByteReader& r, Version v, RigidBodyDef& d) {
  if (v.major >= 2) TELEX_NN_NEED(r.cstring(d.name), "rigid body name without terminating NUL");
  TELEX_NN_NEED(r.get(d.id) && r.get(d.parent_id), "truncated rigid body description");
  TELEX_NN_NEED(r.get(d.offset_m.x) && r.get(d.offset_m.y) && r.get(d.offset_m.z),
                "truncated rigid body offset");
  if (v.major < 3) return {};
  std::int32_t markers = 0;
  TELEX_NN_NEED(r.get(markers), "truncated rigid body marker count");
  TELEX_NN_NEED(markers >= 0 && static_cast<std::size_t>(markers) <= r.remaining() / 16,
                "rigid body marker count exceeds the bytes left");
  // Positions (xyz f32) then active labels (i32), then from 4.0 the names.
  TELEX_NN_NEED(r.skip(static_cast<std::size_t>(markers) * 16), "truncated rigid body markers");
  if (v.major >= 4)
    for (std::int32_t i = 0; i < markers; ++i) {
      std::string name;
      TELEX_NN_NEED(r.cstring(name), "marker name without terminating NUL");
    }
  return {};
}

void write_rigid_body_def(ByteWriter& w, const RigidBodyDef& d, Version v) {
  if (v.major >= 2) w.cstring(d.name);
  w.put(d.id);
  w.put(d.parent_id);
  w.put(d.offset_m.x);
  w.put(d.offset_m.y);
  w.put(d.offset_m.z);
  if (v.major >= 3) w.put(std::int32_t{0});  // no markers: no positions, labels or names
}

bool sized_datasets(Version v) { return v.at_least(4, 1); }

}  // namespace

ParseStatus parse_server_info(std::span<const std::uint8_t> payload, ServerInfo& out) {
  ByteReader r(payload);
  TELEX_NN_NEED(payload.size() >= kServerInfoBytes2, "server info shorter than 264 bytes");
  const auto* name = reinterpret_cast<const char*>(payload.data());
  out.app_name.assign(name, strnlen(name, 256));
  r.skip(256);
  for (auto& b : out.app_version) r.get(b);
  for (auto& b : out.natnet_version_bytes) r.get(b);
  out.natnet_version = Version{out.natnet_version_bytes[0], out.natnet_version_bytes[1]};
  TELEX_NN_NEED(supported(out.natnet_version), "server NatNet version outside 2.0 .. 4.x");
  return {};
}

ParseStatus parse_server_info(std::span<const std::uint8_t> payload, Version version,
                              ServerInfo& out) {
  if (auto s = parse_server_info(payload, out); !s.ok()) return s;
  ByteReader r(payload);
  r.skip(kServerInfoBytes2);
  out.has_connection_info = false;
  if (version.major < 3) {
    TELEX_NN_NEED(r.remaining() == 0, "bytes after a 2.x server info");
    return {};
  }
  std::uint8_t multicast = 0;
  TELEX_NN_NEED(r.get(out.high_res_clock_hz) && r.get(out.data_port) && r.get(multicast),
                "3.0+ server info without its clock frequency, data port and multicast flag");
  for (auto& b : out.multicast_group) TELEX_NN_NEED(r.get(b), "truncated multicast address");
  TELEX_NN_NEED(r.remaining() == 0, "bytes after a 3.0+ server info");
  out.multicast = multicast != 0;
  out.has_connection_info = true;
  return {};
}

ParseStatus parse_model_defs(std::span<const std::uint8_t> payload, Version version,
                             ModelDefs& out) {
  ByteReader r(payload);
  out.rigid_bodies.clear();
  std::int32_t n = 0;
  TELEX_NN_NEED(r.get(n), "truncated dataset count");
  TELEX_NN_NEED(n >= 0 && static_cast<std::size_t>(n) <= r.remaining() / 4,
                "dataset count exceeds the bytes left");
  for (std::int32_t i = 0; i < n; ++i) {
    std::int32_t type = -1;
    TELEX_NN_NEED(r.get(type), "truncated dataset type");
    TELEX_NN_NEED(type == 1, "dataset is not a rigid body (type 1)");
    std::uint32_t bytes = 0;
    if (sized_datasets(version)) TELEX_NN_NEED(r.get(bytes), "truncated dataset byte count");
    const std::size_t start = r.offset();
    RigidBodyDef d;
    if (auto s = read_rigid_body_def(r, version, d); !s.ok()) return s;
    TELEX_NN_NEED(!sized_datasets(version) || r.offset() - start == bytes,
                  "dataset byte count does not match its contents");
    out.rigid_bodies.push_back(std::move(d));
  }
  TELEX_NN_NEED(r.remaining() == 0, "bytes after the last dataset");
  return {};
}

#undef TELEX_NN_NEED

std::vector<std::uint8_t> make_server_info(const ServerInfo& info) {
  const bool v3 = info.natnet_version.major >= 3;
  std::vector<std::uint8_t> p(kServerInfoBytes2, 0);
  std::memcpy(p.data(), info.app_name.data(), std::min<std::size_t>(info.app_name.size(), 255));
  std::memcpy(p.data() + 256, info.app_version.data(), 4);
  p[260] = static_cast<std::uint8_t>(info.natnet_version.major);
  p[261] = static_cast<std::uint8_t>(info.natnet_version.minor);
  if (v3) {
    ByteWriter w(p);
    w.u64(info.high_res_clock_hz);
    w.u16(info.data_port);
    w.u8(info.multicast ? 1 : 0);
    for (auto b : info.multicast_group) w.u8(b);
  }
  return make_packet(kPingResponse, p);
}

std::vector<std::uint8_t> make_model_defs(const ModelDefs& defs, Version version) {
  std::vector<std::uint8_t> p;
  ByteWriter w(p);
  w.put(static_cast<std::int32_t>(defs.rigid_bodies.size()));
  for (const auto& d : defs.rigid_bodies) {
    w.put(std::int32_t{1});
    const std::size_t size_at = w.size();
    if (sized_datasets(version)) w.u32(0);
    write_rigid_body_def(w, d, version);
    if (sized_datasets(version))
      w.patch_u32(size_at, static_cast<std::uint32_t>(w.size() - size_at - 4));
  }
  return make_packet(kModelDef, p);
}

std::vector<std::uint8_t> make_echo_reply(std::uint64_t client_stamp, std::uint64_t server_stamp,
                                          Version version) {
  if (version.major < 3) return make_packet(kUnrecognizedRequest, {});
  std::vector<std::uint8_t> p;
  ByteWriter w(p);
  w.u64(client_stamp);
  w.u64(server_stamp);
  return make_packet(kEchoResponse, p);
}

}  // namespace telex::local::natnet
