// SPDX-License-Identifier: MIT
// The header in front of every encoded stereo pair: which pair, when it was seen, how it is coded.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

namespace telex::video {

// Wire values are fixed; never renumber.
enum class VideoCodec : std::uint8_t {
  H264 = 1,   // one Annex B access unit holding the side-by-side picture (left | right)
  Mjpeg = 2,  // two JPEG images: u32 left length, left JPEG, right JPEG (camera pass-through)
};
std::string_view video_codec_name(VideoCodec codec);  // "h264" | "mjpeg"

// Largest eye side any parser or decoder accepts; bounds every allocation they make.
inline constexpr int kMaxEyeSidePx = 4096;
// Largest payload after the header (a 4096x4096 pair of poor JPEGs stays below it).
inline constexpr std::size_t kMaxPayloadBytes = 32u << 20;

struct EncodedFrameHeader {
  std::uint32_t frame_id = 0;    // the capture's frame id (both eyes share it)
  std::uint32_t encode_seq = 0;  // the encoder's output counter: +1 per pair, so a gap is a loss
  std::int64_t capture_ns = 0;   // the pair's capture time (the older eye's, EyePairer)
  VideoCodec codec = VideoCodec::H264;
  bool is_intra = false;            // decodable alone (an H.264 IDR picture; every MJPEG pair)
  std::uint16_t eye_width_px = 0;   // one eye; the H.264 picture is twice as wide
  std::uint16_t eye_height_px = 0;  //
  std::uint32_t payload_bytes = 0;  // the codec bytes that follow the header, exactly
  // The robot head's joints (yaw, pitch, roll, radians; finite, |angle| <= pi) at capture_ns, as
  // the remote's head loop measured them; none without a head (or from an older remote).
  std::optional<std::array<float, 3>> head_joint_rad;
  bool operator==(const EncodedFrameHeader&) const = default;
};

// Size of the serialized header without a head pose: magic "TV", version, codec, flags, reserved,
// two u16 sides, frame id, encode seq, capture ns, payload length (little-endian). With one (flag
// bit 1) three f32 joint angles follow: kHeaderBytes + kHeadPoseBytes, then the payload. A frame
// without one is byte for byte what header version 1 was before the pose existed.
inline constexpr std::size_t kHeaderBytes = 30;
inline constexpr std::size_t kHeadPoseBytes = 12;
inline constexpr std::uint8_t kHeaderVersion = 1;
// The serialized header's size: kHeaderBytes, plus kHeadPoseBytes with a head pose.
std::size_t header_bytes(const EncodedFrameHeader& header);

enum class HeaderStatus : std::uint8_t {
  Ok = 0,
  Truncated,       // fewer than kHeaderBytes, or fewer payload bytes than the header says
  BadMagic,        // not "TV" or another version
  UnknownCodec,    //
  BadFlags,        // unknown flag bits or the reserved byte other than zero
  BadGeometry,     // a side of 0, odd (H.264 4:2:0 needs even sides) or above kMaxEyeSidePx
  PayloadTooLong,  // payload_bytes above kMaxPayloadBytes
  TrailingBytes,   // more bytes than header + payload_bytes
  BadHeadPose,     // a head joint angle not finite or beyond pi
};
std::string_view header_status_name(HeaderStatus status);

// Appends the header's header_bytes(header) to `out`. The head pose must satisfy what the parser
// checks (the caller's to ensure; head_pose_fits says).
void serialize_header(const EncodedFrameHeader& header, std::vector<std::uint8_t>& out);
// Whether the parser would take these joints: finite, |angle| <= pi.
bool head_pose_fits(const std::array<float, 3>& joint_rad);
// Adds the robot head's joints to a whole encoded frame that has none (the header grows by
// kHeadPoseBytes; the payload moves). False, with `frame` untouched, when it does not parse, has
// a pose already, or the joints do not fit.
bool stamp_head_pose(std::vector<std::uint8_t>& frame, const std::array<float, 3>& joint_rad);

struct ParsedFrame {
  HeaderStatus status = HeaderStatus::Truncated;
  EncodedFrameHeader header;              // valid when status == Ok
  std::span<const std::uint8_t> payload;  // the payload_bytes after the header, when Ok
};

// Parses one whole encoded frame (header, its head pose when flagged, then exactly payload_bytes).
// Reads nothing beyond `bytes`, allocates nothing; any input gives a status.
ParsedFrame parse_frame(std::span<const std::uint8_t> bytes);

}  // namespace telex::video
