// SPDX-License-Identifier: MIT
// Field-by-field little-endian encoding and validating decoding of every wire message.
#include "telex/proto/messages.h"

#include <bit>
#include <cmath>
#include <stdexcept>
#include <string>

#include "byte_io.h"
#include "telex/proto/crc32c.h"
#include "video_messages.h"

namespace telex::proto {
namespace {

using detail::Reader;
using detail::Writer;

void require(bool ok, const char* what) {
  if (!ok) throw std::invalid_argument(std::string("proto::encode: ") + what);
}

void put_payload(Writer& w, const Hello& m) {
  require(m.codecs.size() <= kMaxHelloCodecs, "Hello.codecs has more than 16 entries");
  w.u8(m.version);
  w.u32(m.capabilities);
  w.u16(m.udp_port);
  w.u8(static_cast<std::uint8_t>(m.codecs.size()));
  for (Codec c : m.codecs) w.u8(static_cast<std::uint8_t>(c));
}
void put_payload(Writer& w, const Accept& m) {
  w.u32(m.session_id);
  w.u8(static_cast<std::uint8_t>(m.codec));
  w.u8(static_cast<std::uint8_t>(m.transport));
  w.u16(m.udp_port);
}
void put_payload(Writer& w, const Reject& m) {
  require(m.text.size() <= kMaxText, "Reject.text longer than 1024 bytes");
  w.u16(static_cast<std::uint16_t>(m.reason));
  w.u16(static_cast<std::uint16_t>(m.text.size()));
  w.bytes({reinterpret_cast<const std::uint8_t*>(m.text.data()), m.text.size()});
}
void put_payload(Writer& w, const Heartbeat& m) {
  w.u64(m.t1_ns);
  w.u64(m.t2_ns);
  w.u64(m.t3_ns);
  w.u64(m.t4_ns);
}
void put_payload(Writer& w, const Bye& m) { w.u16(m.reason); }
void put_payload(Writer& w, const StreamConfig& m) {
  w.u16(m.width);
  w.u16(m.height);
  w.f64(m.fx);
  w.f64(m.fy);
  w.f64(m.cx);
  w.f64(m.cy);
  for (double t : m.registration.t_eye_depth_m) w.f64(t);
  w.f64(m.registration.scale_x);
  w.f64(m.registration.scale_y);
  w.f64(m.registration.shift_x_px);
  w.f64(m.registration.shift_y_px);
  w.u16(m.tile_width);
  w.u16(m.tile_height);
  w.u16(m.grid_cols);
  w.u16(m.grid_rows);
  w.u8(static_cast<std::uint8_t>(m.codec));
  w.f32(m.fps);
}
void put_payload(Writer& w, const DepthTile& m) {
  w.u16(m.tile_index);
  w.u16(m.x);
  w.u16(m.y);
  w.u16(m.w);
  w.u16(m.h);
  w.u8(static_cast<std::uint8_t>(m.codec));
  w.u32(static_cast<std::uint32_t>(m.payload.size()));
  w.bytes(m.payload);
}
constexpr float kPiF = 3.14159265f;

void put_head(Writer& w, bool valid, const std::array<float, 3>& joint_rad) {
  w.u8(valid ? 1 : 0);
  for (float a : joint_rad) {
    require(!valid || (std::isfinite(a) && std::abs(a) <= kPiF),
            "head joint angle not finite or beyond pi");
    w.f32(valid ? a : 0.0f);
  }
}

void put_payload(Writer& w, const FrameManifest& m) {
  require(m.changed_tiles.size() <= kMaxManifestTiles, "FrameManifest lists more than 4096 tiles");
  w.u32(m.frame_id);
  w.u16(m.tile_count);
  w.u8(m.key_frame ? 1 : 0);
  w.u16(static_cast<std::uint16_t>(m.changed_tiles.size()));
  for (std::uint16_t t : m.changed_tiles) w.u16(t);
  put_head(w, m.head.valid, m.head.joint_rad);
}
void put_payload(Writer& w, const EncodedVideo& m) { detail::put_video(w, m); }
void put_payload(Writer& w, const PictureLoss& m) { detail::put_picture_loss(w, m); }
void put_payload(Writer& w, const ReceiverReport& m) { detail::put_receiver_report(w, m); }
void put_payload(Writer& w, const VideoNack& m) { detail::put_video_nack(w, m); }
void put_payload(Writer& w, const RoiRequest& m) {
  require(m.rects.size() <= kMaxRoiRects, "RoiRequest has more than 16 rectangles");
  w.u8(static_cast<std::uint8_t>(m.rects.size()));
  for (const RoiRect& r : m.rects) {
    w.u16(r.x);
    w.u16(r.y);
    w.u16(r.w);
    w.u16(r.h);
    w.u8(r.priority);
  }
}
void put_payload(Writer& w, const Stats& m) {
  require(m.counters.size() <= kMaxStatsEntries, "Stats has more than 64 counters");
  w.u8(static_cast<std::uint8_t>(m.counters.size()));
  for (const auto& [key, value] : m.counters) {
    require(!key.empty() && key.size() <= kMaxStatsKey, "Stats key empty or longer than 64");
    w.u8(static_cast<std::uint8_t>(key.size()));
    w.bytes({reinterpret_cast<const std::uint8_t*>(key.data()), key.size()});
    w.u64(value);
  }
}

void put_payload(Writer& w, const HeadCommand& m) {
  w.u64(m.operator_ns);
  for (float a : m.joint_rad) {
    require(std::isfinite(a) && std::abs(a) <= kPiF, "HeadCommand angle not finite or beyond pi");
    w.f32(a);
  }
  require(static_cast<std::uint8_t>(m.deadman) <= kMaxDeadmanState,
          "HeadCommand dead-man state not 0, 1 or 2");
  w.u32(m.sample_id);
  w.u32(m.sample_age_us);
  w.u8(static_cast<std::uint8_t>(m.deadman));
}

void put_payload(Writer& w, const TileNack& m) {
  require(!m.tiles.empty() && m.tiles.size() <= kMaxManifestTiles,
          "TileNack lists no tile or more than 4096");
  for (std::size_t i = 1; i < m.tiles.size(); ++i)
    require(m.tiles[i - 1] < m.tiles[i], "TileNack tile list not strictly increasing");
  w.u32(m.frame_id);
  w.u16(static_cast<std::uint16_t>(m.tiles.size()));
  for (std::uint16_t t : m.tiles) w.u16(t);
}

void put_header(Writer& w, const Header& h) {
  w.u32(h.magic);
  w.u8(h.version);
  w.u8(static_cast<std::uint8_t>(h.type));
  w.u16(h.flags);
  w.u32(h.session_id);
  w.u32(h.seq);
  w.u32(h.frame_id);
  w.u64(h.capture_ns);
  w.u32(h.payload_len);
  w.u32(h.crc32c);
}

// ---- decoding ------------------------------------------------------------------------------

struct Bad {
  ErrorReason reason;
  const char* detail;
};
using PayloadResult = std::variant<Message, Bad>;

Bad bad(const char* detail) { return {ErrorReason::BadPayload, detail}; }
Bad truncated(const char* detail) { return {ErrorReason::Truncated, detail}; }

bool finite(double v) { return std::isfinite(v); }

PayloadResult get_hello(Reader& r) {
  Hello m;
  m.version = r.u8();
  m.capabilities = r.u32();
  m.udp_port = r.u16();
  const std::size_t n = r.u8();
  if (!r.ok()) return truncated("Hello fixed fields");
  if (n > kMaxHelloCodecs) return bad("Hello codec count above 16");
  auto codecs = r.bytes(n);
  if (!r.ok()) return truncated("Hello codec list");
  for (std::uint8_t c : codecs) {
    if (!is_valid_codec(c)) return bad("Hello lists an unknown codec");
    m.codecs.push_back(static_cast<Codec>(c));
  }
  return m;
}
PayloadResult get_accept(Reader& r) {
  Accept m;
  m.session_id = r.u32();
  const std::uint8_t codec = r.u8();
  const std::uint8_t transport = r.u8();
  m.udp_port = r.u16();
  if (!r.ok()) return truncated("Accept fields");
  if (!is_valid_codec(codec)) return bad("Accept codec unknown");
  if (transport > 1) return bad("Accept transport unknown");
  m.codec = static_cast<Codec>(codec);
  m.transport = static_cast<Transport>(transport);
  return m;
}
PayloadResult get_reject(Reader& r) {
  Reject m;
  m.reason = static_cast<RejectReason>(r.u16());
  const std::size_t n = r.u16();
  if (!r.ok()) return truncated("Reject fields");
  if (n > kMaxText) return bad("Reject text longer than 1024");
  auto text = r.bytes(n);
  if (!r.ok()) return truncated("Reject text");
  m.text.assign(text.begin(), text.end());
  return m;
}
PayloadResult get_heartbeat(Reader& r) {
  Heartbeat m;
  m.t1_ns = r.u64();
  m.t2_ns = r.u64();
  m.t3_ns = r.u64();
  m.t4_ns = r.u64();
  if (!r.ok()) return truncated("Heartbeat timestamps");
  return m;
}
PayloadResult get_bye(Reader& r) {
  Bye m;
  m.reason = r.u16();
  if (!r.ok()) return truncated("Bye reason");
  return m;
}
PayloadResult get_stream_config(Reader& r) {
  StreamConfig m;
  m.width = r.u16();
  m.height = r.u16();
  m.fx = r.f64();
  m.fy = r.f64();
  m.cx = r.f64();
  m.cy = r.f64();
  for (double& t : m.registration.t_eye_depth_m) t = r.f64();
  m.registration.scale_x = r.f64();
  m.registration.scale_y = r.f64();
  m.registration.shift_x_px = r.f64();
  m.registration.shift_y_px = r.f64();
  m.tile_width = r.u16();
  m.tile_height = r.u16();
  m.grid_cols = r.u16();
  m.grid_rows = r.u16();
  const std::uint8_t codec = r.u8();
  m.fps = r.f32();
  if (!r.ok()) return truncated("StreamConfig fields");
  if (!is_valid_codec(codec)) return bad("StreamConfig codec unknown");
  m.codec = static_cast<Codec>(codec);
  if (!finite(m.fx) || !finite(m.fy) || !finite(m.cx) || !finite(m.cy) || m.fx <= 0 || m.fy <= 0)
    return bad("StreamConfig intrinsics not finite/positive");
  for (double t : m.registration.t_eye_depth_m)
    if (!finite(t)) return bad("StreamConfig registration translation not finite");
  if (!finite(m.registration.scale_x) || !finite(m.registration.scale_y) ||
      !finite(m.registration.shift_x_px) || !finite(m.registration.shift_y_px))
    return bad("StreamConfig registration not finite");
  if (!std::isfinite(m.fps) || m.fps <= 0.0f) return bad("StreamConfig fps not finite/positive");
  if (m.width == 0 || m.height == 0 || m.tile_width == 0 || m.tile_height == 0 ||
      m.tile_width > m.width || m.tile_height > m.height)
    return {Bad{ErrorReason::BadTileGeometry, "StreamConfig frame or tile size"}};
  if (m.grid_cols != (m.width + m.tile_width - 1) / m.tile_width ||
      m.grid_rows != (m.height + m.tile_height - 1) / m.tile_height)
    return {Bad{ErrorReason::BadTileGeometry, "StreamConfig grid disagrees with frame/tile size"}};
  return m;
}
PayloadResult get_depth_tile(Reader& r, const DecodeLimits& lim) {
  DepthTile m;
  m.tile_index = r.u16();
  m.x = r.u16();
  m.y = r.u16();
  m.w = r.u16();
  m.h = r.u16();
  const std::uint8_t codec = r.u8();
  const std::uint32_t n = r.u32();
  if (!r.ok()) return truncated("DepthTile fields");
  if (m.w == 0 || m.h == 0) return {Bad{ErrorReason::BadTileGeometry, "DepthTile empty rectangle"}};
  if (static_cast<std::uint64_t>(m.w) * m.h > lim.max_tile_pixels)
    return {Bad{ErrorReason::DecompressionBomb, "DepthTile claims more pixels than allowed"}};
  if (lim.frame_width != 0 && lim.frame_height != 0 &&
      (m.x + m.w > lim.frame_width || m.y + m.h > lim.frame_height))
    return {Bad{ErrorReason::BadTileGeometry, "DepthTile rectangle outside the frame"}};
  if (!is_valid_codec(codec)) return bad("DepthTile codec unknown");
  m.codec = static_cast<Codec>(codec);
  if (n != r.remaining()) {
    return n > r.remaining() ? truncated("DepthTile payload") : bad("DepthTile trailing bytes");
  }
  if (m.codec == Codec::Raw && n != 2u * m.w * m.h)
    return {Bad{ErrorReason::DecompressionBomb, "DepthTile raw payload size differs from w*h*2"}};
  auto p = r.bytes(n);
  m.payload.assign(p.begin(), p.end());
  return m;
}
PayloadResult get_manifest(Reader& r) {
  FrameManifest m;
  m.frame_id = r.u32();
  m.tile_count = r.u16();
  const std::uint8_t key = r.u8();
  const std::size_t n = r.u16();
  if (!r.ok()) return truncated("FrameManifest fields");
  if (key > 1) return bad("FrameManifest key flag not 0/1");
  m.key_frame = key == 1;
  if (m.tile_count == 0 || m.tile_count > kMaxManifestTiles)
    return {Bad{ErrorReason::BadTileGeometry, "FrameManifest tile count 0 or above 4096"}};
  if (n > m.tile_count) return bad("FrameManifest lists more tiles than the grid has");
  if (r.remaining() < 2 * n) return truncated("FrameManifest tile list");
  m.changed_tiles.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint16_t t = r.u16();
    if (t >= m.tile_count) return {Bad{ErrorReason::BadTileGeometry, "FrameManifest tile index"}};
    if (!m.changed_tiles.empty() && t <= m.changed_tiles.back())
      return bad("FrameManifest tile list not strictly increasing");
    m.changed_tiles.push_back(t);
  }
  const std::uint8_t head = r.u8();
  for (float& a : m.head.joint_rad) a = r.f32();
  if (!r.ok()) return truncated("FrameManifest head joints");
  if (head > 1) return bad("FrameManifest head flag not 0/1");
  m.head.valid = head == 1;
  for (float a : m.head.joint_rad)
    if (!std::isfinite(a) || std::abs(a) > kPiF)
      return bad("FrameManifest head joint not finite or beyond pi");
  // Without the valid flag the joints are all-zero bytes: -0.0 compares equal to 0 but would not
  // re-encode to the same bytes (found by datagram_fuzz).
  if (!m.head.valid)
    for (float a : m.head.joint_rad)
      if (std::bit_cast<std::uint32_t>(a) != 0u)
        return bad("FrameManifest head joints set without the valid flag");
  return m;
}

PayloadResult get_head_command(Reader& r) {
  HeadCommand m;
  m.operator_ns = r.u64();
  for (float& a : m.joint_rad) a = r.f32();
  m.sample_id = r.u32();
  m.sample_age_us = r.u32();
  const std::uint8_t deadman = r.u8();
  if (!r.ok()) return truncated("HeadCommand fields");
  for (float a : m.joint_rad)
    if (!std::isfinite(a) || std::abs(a) > kPiF)
      return bad("HeadCommand angle not finite or beyond pi");
  if (deadman > kMaxDeadmanState) return bad("HeadCommand dead-man state not 0, 1 or 2");
  m.deadman = static_cast<DeadmanState>(deadman);
  return m;
}
// The eyes' messages (video_messages.cpp).
template <typename M, typename Get>
PayloadResult get_eyes(Reader& r, Get get) {
  M m;
  if (const auto e = get(r, m)) return Bad{e->reason, e->detail};
  return m;
}
PayloadResult get_roi(Reader& r, const DecodeLimits& lim) {
  RoiRequest m;
  const std::size_t n = r.u8();
  if (!r.ok()) return truncated("RoiRequest count");
  if (n > kMaxRoiRects) return bad("RoiRequest more than 16 rectangles");
  if (r.remaining() < 9 * n) return truncated("RoiRequest rectangles");
  for (std::size_t i = 0; i < n; ++i) {
    RoiRect q;
    q.x = r.u16();
    q.y = r.u16();
    q.w = r.u16();
    q.h = r.u16();
    q.priority = r.u8();
    if (q.w == 0 || q.h == 0) return {Bad{ErrorReason::BadTileGeometry, "RoiRequest empty rect"}};
    if (lim.frame_width != 0 && lim.frame_height != 0 &&
        (q.x + q.w > lim.frame_width || q.y + q.h > lim.frame_height))
      return {Bad{ErrorReason::BadTileGeometry, "RoiRequest rect outside the frame"}};
    m.rects.push_back(q);
  }
  return m;
}
PayloadResult get_stats(Reader& r) {
  Stats m;
  const std::size_t n = r.u8();
  if (!r.ok()) return truncated("Stats count");
  if (n > kMaxStatsEntries) return bad("Stats more than 64 counters");
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t len = r.u8();
    if (!r.ok()) return truncated("Stats key length");
    if (len == 0 || len > kMaxStatsKey) return bad("Stats key empty or longer than 64");
    auto key = r.bytes(len);
    const std::uint64_t v = r.u64();
    if (!r.ok()) return truncated("Stats entry");
    for (std::uint8_t c : key)
      if (c < 0x21 || c > 0x7E) return bad("Stats key not printable ASCII");
    m.counters.emplace_back(std::string(key.begin(), key.end()), v);
  }
  return m;
}

PayloadResult get_nack(Reader& r) {
  TileNack m;
  m.frame_id = r.u32();
  const std::size_t n = r.u16();
  if (!r.ok()) return truncated("TileNack fields");
  if (n == 0 || n > kMaxManifestTiles) return bad("TileNack lists no tile or more than 4096");
  if (r.remaining() < 2 * n) return truncated("TileNack tile list");
  m.tiles.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint16_t t = r.u16();
    if (t >= kMaxManifestTiles) return {Bad{ErrorReason::BadTileGeometry, "TileNack tile index"}};
    if (!m.tiles.empty() && t <= m.tiles.back())
      return bad("TileNack tile list not strictly increasing");
    m.tiles.push_back(t);
  }
  return m;
}

PayloadResult get_payload(MsgType type, Reader& r, const DecodeLimits& lim) {
  switch (type) {
    case MsgType::Hello:
      return get_hello(r);
    case MsgType::Accept:
      return get_accept(r);
    case MsgType::Reject:
      return get_reject(r);
    case MsgType::Heartbeat:
      return get_heartbeat(r);
    case MsgType::Bye:
      return get_bye(r);
    case MsgType::StreamConfig:
      return get_stream_config(r);
    case MsgType::DepthTile:
      return get_depth_tile(r, lim);
    case MsgType::FrameManifest:
      return get_manifest(r);
    case MsgType::EncodedVideo:
      return get_eyes<EncodedVideo>(r, detail::get_video);
    case MsgType::RoiRequest:
      return get_roi(r, lim);
    case MsgType::Stats:
      return get_stats(r);
    case MsgType::TileNack:
      return get_nack(r);
    case MsgType::HeadCommand:
      return get_head_command(r);
    case MsgType::PictureLoss:
      return get_eyes<PictureLoss>(r, detail::get_picture_loss);
    case MsgType::ReceiverReport:
      return get_eyes<ReceiverReport>(r, detail::get_receiver_report);
    case MsgType::VideoNack:
      return get_eyes<VideoNack>(r, detail::get_video_nack);
  }
  return Bad{ErrorReason::UnknownType, "message type"};
}

Result failure(ErrorReason reason, const char* detail) {
  Result r;
  r.error = reason;
  r.detail = detail;
  return r;
}

}  // namespace

std::string_view msg_type_name(MsgType type) {
  static constexpr std::string_view kNames[kMsgTypeCount] = {
      "Hello",       "Accept",        "Reject",         "Heartbeat",  "Bye",   "StreamConfig",
      "DepthTile",   "FrameManifest", "EncodedVideo",   "RoiRequest", "Stats", "TileNack",
      "HeadCommand", "PictureLoss",   "ReceiverReport", "VideoNack"};
  const auto i = static_cast<std::size_t>(type);
  return i < kMsgTypeCount ? kNames[i] : std::string_view("unknown");
}

std::string_view error_reason_name(ErrorReason reason) {
  static constexpr std::string_view kNames[kErrorReasonCount] = {
      "Truncated",   "BadMagic",    "BadVersion",      "BadLength",
      "BadChecksum", "UnknownType", "BadTileGeometry", "DecompressionBomb",
      "BadPayload",  "AuthFailed",  "Unsealed",        "Replayed"};
  const auto i = static_cast<std::size_t>(reason);
  return i < kErrorReasonCount ? kNames[i] : std::string_view("unknown");
}

MsgType type_of(const Message& message) { return static_cast<MsgType>(message.index()); }

std::vector<std::uint8_t> encode(const Header& header, const Message& message) {
  std::vector<std::uint8_t> out;
  out.reserve(kHeaderSize + 64);
  Writer w(out);
  Header h = header;
  h.type = type_of(message);
  h.payload_len = 0;
  h.crc32c = 0;
  put_header(w, h);
  std::visit([&](const auto& m) { put_payload(w, m); }, message);
  const std::size_t payload = out.size() - kHeaderSize;
  require(payload <= 0xFFFFFFFFu - kHeaderSize, "payload larger than 4 GiB");
  h.payload_len = static_cast<std::uint32_t>(payload);
  // Patch payload_len (offset 28) and then the CRC (offset 32) computed with the CRC field zero.
  for (int i = 0; i < 4; ++i) out[28 + i] = static_cast<std::uint8_t>(h.payload_len >> (8 * i));
  const std::uint32_t crc = crc32c(out);
  for (int i = 0; i < 4; ++i) out[32 + i] = static_cast<std::uint8_t>(crc >> (8 * i));
  return out;
}

std::vector<std::uint8_t> encode_stream(const Header& header, const Message& message) {
  const std::vector<std::uint8_t> msg = encode(header, message);
  std::vector<std::uint8_t> out;
  out.reserve(4 + msg.size());
  Writer w(out);
  w.u32(static_cast<std::uint32_t>(msg.size()));
  w.bytes(msg);
  return out;
}

std::optional<Error> decode_header(std::span<const std::uint8_t> bytes, Header& h,
                                   const DecodeLimits& limits) {
  Reader r(bytes);
  h.magic = r.u32();
  h.version = r.u8();
  const std::uint8_t type = r.u8();
  h.type = static_cast<MsgType>(type);
  h.flags = r.u16();
  h.session_id = r.u32();
  h.seq = r.u32();
  h.frame_id = r.u32();
  h.capture_ns = r.u64();
  h.payload_len = r.u32();
  h.crc32c = r.u32();
  if (!r.ok()) return Error{ErrorReason::Truncated, "header shorter than 36 bytes"};
  if (h.magic != kMagic) return Error{ErrorReason::BadMagic, "header magic is not TLX1"};
  if (static_cast<std::uint64_t>(h.payload_len) + kHeaderSize > limits.max_message_bytes)
    return Error{ErrorReason::BadLength, "header payload_len above the message bound"};
  return std::nullopt;
}

Result decode(std::span<const std::uint8_t> bytes, const DecodeLimits& limits) {
  Header h;
  if (auto e = decode_header(bytes, h, limits)) return failure(e->reason, e->detail);
  const std::size_t have = bytes.size() - kHeaderSize;
  if (have < h.payload_len)
    return failure(ErrorReason::Truncated, "payload shorter than payload_len");
  if (have > h.payload_len) return failure(ErrorReason::BadLength, "bytes beyond payload_len");
  // CRC over the header with its CRC field taken as zero, then the payload.
  static constexpr std::uint8_t kZero[4] = {0, 0, 0, 0};
  std::uint32_t crc = crc32c(bytes.first(32));
  crc = crc32c(kZero, crc);
  crc = crc32c(bytes.subspan(kHeaderSize), crc);
  if (crc != h.crc32c) return failure(ErrorReason::BadChecksum, "CRC32C mismatch");
  if (h.version != kProtocolVersion) return failure(ErrorReason::BadVersion, "header version");
  if (static_cast<std::uint8_t>(h.type) >= kMsgTypeCount)
    return failure(ErrorReason::UnknownType, "header message type");
  Reader r(bytes.subspan(kHeaderSize));
  PayloadResult p = get_payload(h.type, r, limits);
  if (auto* b = std::get_if<Bad>(&p)) return failure(b->reason, b->detail);
  if (r.remaining() != 0) return failure(ErrorReason::BadPayload, "trailing bytes after payload");
  Result out;
  out.envelope = Envelope{h, std::move(std::get<Message>(p))};
  return out;
}

}  // namespace telex::proto
