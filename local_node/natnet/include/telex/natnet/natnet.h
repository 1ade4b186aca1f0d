// SPDX-License-Identifier: MIT
// OptiTrack NatNet subset: packet framing, server info, FRAMEOFDATA for NatNet 2.x-4.x (pure).
// Every version's FRAMEOFDATA layout is NaturalPoint's reference decoder's of that version, field
// by field: PacketClient.cpp of SDK 2.5 .. 3.1 and NatNetClient.py of SDK 4.x (docs/HARDWARE.md,
// "NatNet versions", cites each line).
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace telex::local::natnet {

enum MessageId : std::uint16_t {
  kPing = 0,  // NAT_CONNECT in NatNet 4 naming
  kPingResponse = 1,
  kRequest = 2,
  kResponse = 3,
  kRequestModelDef = 4,
  kModelDef = 5,
  kRequestFrameOfData = 6,
  kFrameOfData = 7,
  kMessageString = 8,
  kDisconnect = 9,
  kKeepAlive = 10,
  kEchoRequest = 12,   // 3.0+: u64 client stamp
  kEchoResponse = 13,  // 3.0+: u64 client stamp echoed, u64 server stamp at receipt
  kUnrecognizedRequest = 100,
};

inline constexpr int kCommandPort = 1510;
inline constexpr int kDataPort = 1511;
inline constexpr const char* kMulticastGroup = "239.255.42.99";
inline constexpr std::size_t kMaxPacketBytes = 65507;  // largest UDP payload over IPv4

struct Version {
  int major = 3;
  int minor = 1;
  bool at_least(int ma, int mi) const { return major > ma || (major == ma && minor >= mi); }
  bool operator==(const Version&) const = default;
};

struct Vec3f {
  float x = 0, y = 0, z = 0;
  bool operator==(const Vec3f&) const = default;
};

struct RigidBody {
  std::int32_t id = 0;
  Vec3f p_m;
  float qx = 0, qy = 0, qz = 0, qw = 1;
  std::vector<Vec3f> markers;  // only sent before NatNet 3.0
  float mean_error_m = 0;      // 2.0+
  bool tracking_valid = true;  // params bit 0, 2.6+ (always true before)
};

struct MarkerSet {
  std::string name;
  std::vector<Vec3f> markers;
};

struct Skeleton {
  std::int32_t id = 0;
  std::vector<RigidBody> bones;
};

struct LabeledMarker {
  std::int32_t id = 0;  // model id << 16 | marker id
  Vec3f p_m;
  float size_m = 0;
  std::int16_t params = 0;  // 2.6+
  float residual_m = 0;     // 3.0+
};

struct AnalogDevice {  // force plates and other devices share this layout
  std::int32_t id = 0;
  std::vector<std::vector<float>> channels;  // per channel, its sub-frames
};

struct Frame {
  std::uint32_t frame_number = 0;
  std::vector<MarkerSet> marker_sets;
  std::vector<Vec3f> unlabeled_markers;
  std::vector<RigidBody> rigid_bodies;
  std::vector<Skeleton> skeletons;        // 2.1+
  std::uint32_t asset_section_bytes = 0;  // 4.1+: skipped by byte count, not parsed
  std::int32_t asset_count = 0;
  std::vector<LabeledMarker> labeled_markers;  // 2.3+
  std::vector<AnalogDevice> force_plates;      // 2.9+
  std::vector<AnalogDevice> devices;           // 2.11+
  float software_latency_s = 0;                // 2.x only: removed in 3.0
  std::uint32_t timecode = 0;                  // 2.3+
  std::uint32_t timecode_sub = 0;              // 2.3+
  double timestamp_s = 0;                      // 2.6+, f32 before 2.7
  std::uint64_t stamp_mid_exposure = 0, stamp_data_received = 0, stamp_transmit = 0;  // 3.0+
  std::uint32_t precision_s = 0, precision_frac = 0;                                  // 4.1+
  std::int16_t params = 0;  // 2.6+: bit 0 recording, bit 1 tracked models changed

  void clear();  // keeps the top-level arrays' capacity for a reused Frame
  const RigidBody* find_body(std::int32_t id) const;
};

// SERVERINFO (message 1). Up to 2.x: app name[256], app version[4], NatNet version[4] (264
// bytes). From 3.0 (PacketClient 3.0's sSender_Server, as Motive 2.1 sends it: 279 bytes) the
// connection fields follow.
struct ServerInfo {
  std::string app_name;
  std::array<std::uint8_t, 4> app_version{};
  Version natnet_version;
  std::array<std::uint8_t, 4> natnet_version_bytes{};
  bool has_connection_info = false;  // 3.0+: the four fields below were sent
  std::uint64_t high_res_clock_hz = 0;
  std::uint16_t data_port = 0;
  bool multicast = false;
  std::array<std::uint8_t, 4> multicast_group{};
};
inline constexpr std::size_t kServerInfoBytes2 = 264;  // payload, NatNet 2.x
inline constexpr std::size_t kServerInfoBytes3 = 279;  // payload, NatNet 3.0+

// MODELDEF (message 5), the rigid-body datasets (type 1) in `version`'s layout: name (2.0+), id,
// parent id, offset xyz; from 3.0 a marker count, its positions and active labels; from 4.0 the
// markers' names; from 4.1 each dataset's byte count after its type (NatNetClient.py 4.1).
struct RigidBodyDef {
  std::string name;
  std::int32_t id = 0;
  std::int32_t parent_id = -1;
  Vec3f offset_m;
  bool operator==(const RigidBodyDef&) const = default;
};
struct ModelDefs {
  std::vector<RigidBodyDef> rigid_bodies;
};

// Why a packet was rejected; nullptr reason = accepted. `offset` is where parsing stopped.
struct ParseStatus {
  const char* reason = nullptr;
  std::size_t offset = 0;
  bool ok() const { return reason == nullptr; }
};

struct PacketView {
  std::uint16_t message_id = 0;
  std::span<const std::uint8_t> payload;  // exactly the header's byte count
};

// Splits a datagram into message id and payload; rejects a datagram shorter than its header says.
ParseStatus parse_packet(std::span<const std::uint8_t> datagram, PacketView& out);

// FRAMEOFDATA payload (after the 4-byte header) in the layout of `version`. Never reads outside
// `payload`; every count is checked against the bytes left before anything is allocated.
ParseStatus parse_frame(std::span<const std::uint8_t> payload, Version version, Frame& out);

// PINGRESPONSE payload: app name[256], app version[4], NatNet version[4] (more bytes ignored).
ParseStatus parse_server_info(std::span<const std::uint8_t> payload, ServerInfo& out);

// PINGRESPONSE payload: 264 bytes, then from 3.0 the connection fields when they were sent
// (info.has_connection_info).
ParseStatus parse_server_info(std::span<const std::uint8_t> payload, Version version,
                              ServerInfo& out);
// MODELDEF payload in `version`'s layout; a dataset other than a rigid body is rejected.
ParseStatus parse_model_defs(std::span<const std::uint8_t> payload, Version version,
                             ModelDefs& out);

// Builders for the client's connect request and for the simulator's replies and frames.
std::vector<std::uint8_t> make_packet(std::uint16_t message_id,
                                      std::span<const std::uint8_t> payload);
std::vector<std::uint8_t> make_ping(std::string_view app_name);
// SERVERINFO in the layout of info.natnet_version: 268 bytes for 2.x, 283 from 3.0.
std::vector<std::uint8_t> make_server_info(const ServerInfo& info);
std::vector<std::uint8_t> make_model_defs(const ModelDefs& defs, Version version);
// The reply to an ECHOREQUEST: from 3.0 an ECHORESPONSE (the client's stamp, then the server's);
// before 3.0 there was no echo, and the reply is UNRECOGNIZED_REQUEST with no payload.
std::vector<std::uint8_t> make_echo_reply(std::uint64_t client_stamp, std::uint64_t server_stamp,
                                          Version version);
// Complete FRAMEOFDATA datagram (header + payload) in `version`'s layout.
std::vector<std::uint8_t> encode_frame(const Frame& frame, Version version);

// "2", "3.1", "4.1.0.0" -> Version; throws std::invalid_argument naming the text and 2.0-4.x.
Version parse_version(std::string_view text);
bool supported(Version v);  // 2.0 .. 4.x

}  // namespace telex::local::natnet
