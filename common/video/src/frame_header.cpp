// SPDX-License-Identifier: MIT
// The encoded pair's header: serialization and the bounded parser.
#include "telex/video/frame_header.h"

#include <algorithm>
#include <cmath>

#include "telex/base/byte_cursor.h"

namespace telex::video {

namespace {
constexpr std::uint8_t kMagic0 = 'T';
constexpr std::uint8_t kMagic1 = 'V';
constexpr std::uint8_t kFlagIntra = 0x01;
constexpr std::uint8_t kFlagHeadPose = 0x02;
constexpr float kPi = 3.14159265358979323846f;

bool valid_side(std::uint16_t side_px, VideoCodec codec) {
  if (side_px == 0 || side_px > kMaxEyeSidePx) return false;
  return codec != VideoCodec::H264 || side_px % 2 == 0;
}
}  // namespace

std::string_view video_codec_name(VideoCodec codec) {
  switch (codec) {
    case VideoCodec::H264:
      return "h264";
    case VideoCodec::Mjpeg:
      return "mjpeg";
  }
  return "unknown";
}

std::string_view header_status_name(HeaderStatus status) {
  switch (status) {
    case HeaderStatus::Ok:
      return "ok";
    case HeaderStatus::Truncated:
      return "truncated";
    case HeaderStatus::BadMagic:
      return "bad magic or version";
    case HeaderStatus::UnknownCodec:
      return "unknown codec";
    case HeaderStatus::BadFlags:
      return "bad flags";
    case HeaderStatus::BadGeometry:
      return "bad geometry";
    case HeaderStatus::PayloadTooLong:
      return "payload too long";
    case HeaderStatus::TrailingBytes:
      return "trailing bytes";
    case HeaderStatus::BadHeadPose:
      return "head pose not finite or beyond pi";
  }
  return "unknown";
}

std::size_t header_bytes(const EncodedFrameHeader& header) {
  return kHeaderBytes + (header.head_joint_rad ? kHeadPoseBytes : 0);
}

bool head_pose_fits(const std::array<float, 3>& joint_rad) {
  return std::all_of(joint_rad.begin(), joint_rad.end(),
                     [](float a) { return std::isfinite(a) && std::abs(a) <= kPi; });
}

void serialize_header(const EncodedFrameHeader& header, std::vector<std::uint8_t>& out) {
  ByteWriter w(out);
  w.u8(kMagic0);
  w.u8(kMagic1);
  w.u8(kHeaderVersion);
  w.u8(static_cast<std::uint8_t>(header.codec));
  w.u8(static_cast<std::uint8_t>((header.is_intra ? kFlagIntra : 0) |
                                 (header.head_joint_rad ? kFlagHeadPose : 0)));
  w.u8(0);
  w.u16(header.eye_width_px);
  w.u16(header.eye_height_px);
  w.u32(header.frame_id);
  w.u32(header.encode_seq);
  w.put(header.capture_ns);
  w.u32(header.payload_bytes);
  if (header.head_joint_rad)
    for (const float a : *header.head_joint_rad) w.put(a);
}

bool stamp_head_pose(std::vector<std::uint8_t>& frame, const std::array<float, 3>& joint_rad) {
  if (!head_pose_fits(joint_rad)) return false;
  ParsedFrame parsed = parse_frame(frame);
  if (parsed.status != HeaderStatus::Ok || parsed.header.head_joint_rad) return false;
  parsed.header.head_joint_rad = joint_rad;
  std::vector<std::uint8_t> header;
  serialize_header(parsed.header, header);
  // The old header's bytes become the new one's first kHeaderBytes; the pose goes in after them.
  frame.insert(frame.begin() + kHeaderBytes, header.begin() + kHeaderBytes, header.end());
  std::copy(header.begin(), header.begin() + kHeaderBytes, frame.begin());
  return true;
}

ParsedFrame parse_frame(std::span<const std::uint8_t> bytes) {
  ParsedFrame parsed;
  ByteReader r(bytes);
  const std::uint8_t m0 = r.u8(), m1 = r.u8(), version = r.u8(), codec = r.u8();
  const std::uint8_t flags = r.u8(), reserved = r.u8();
  EncodedFrameHeader& h = parsed.header;
  h.eye_width_px = r.u16();
  h.eye_height_px = r.u16();
  h.frame_id = r.u32();
  h.encode_seq = r.u32();
  h.capture_ns = r.read<std::int64_t>();
  h.payload_bytes = r.u32();
  if (!r.ok()) return parsed;  // Truncated
  if (m0 != kMagic0 || m1 != kMagic1 || version != kHeaderVersion) {
    parsed.status = HeaderStatus::BadMagic;
    return parsed;
  }
  if (codec != static_cast<std::uint8_t>(VideoCodec::H264) &&
      codec != static_cast<std::uint8_t>(VideoCodec::Mjpeg)) {
    parsed.status = HeaderStatus::UnknownCodec;
    return parsed;
  }
  h.codec = static_cast<VideoCodec>(codec);
  if ((flags & ~(kFlagIntra | kFlagHeadPose)) != 0 || reserved != 0) {
    parsed.status = HeaderStatus::BadFlags;
    return parsed;
  }
  h.is_intra = (flags & kFlagIntra) != 0;
  if ((flags & kFlagHeadPose) != 0) {
    std::array<float, 3> joint_rad{};
    for (float& a : joint_rad) a = r.read<float>();
    if (!r.ok()) return parsed;  // Truncated
    if (!head_pose_fits(joint_rad)) {
      parsed.status = HeaderStatus::BadHeadPose;
      return parsed;
    }
    h.head_joint_rad = joint_rad;
  }
  if (!valid_side(h.eye_width_px, h.codec) || !valid_side(h.eye_height_px, h.codec)) {
    parsed.status = HeaderStatus::BadGeometry;
    return parsed;
  }
  if (h.payload_bytes > kMaxPayloadBytes) {
    parsed.status = HeaderStatus::PayloadTooLong;
    return parsed;
  }
  if (r.remaining() < h.payload_bytes) return parsed;  // Truncated
  if (r.remaining() > h.payload_bytes) {
    parsed.status = HeaderStatus::TrailingBytes;
    return parsed;
  }
  parsed.payload = r.bytes(h.payload_bytes);
  parsed.status = HeaderStatus::Ok;
  return parsed;
}

}  // namespace telex::video
