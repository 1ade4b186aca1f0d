// SPDX-License-Identifier: MIT
// Wire messages: the fixed 36-byte header, one struct per payload, and their explicit LE encoding.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <variant>
#include <vector>

#include "telex/proto/depth_codec.h"
#include "telex/video/frame_header.h"

namespace telex::proto {

// "TLX1" in wire byte order (bytes 'T','L','X','1'), read as a little-endian u32.
inline constexpr std::uint32_t kMagic = 0x31584C54u;
// 5: message 8 carries an encoded stereo pair (EncodedVideo) instead of one eye's JPEG; messages
// 13 and 14 (PictureLoss, ReceiverReport) are new. 6: message 15 (VideoNack) asks for lost pairs
// again. 7: an encoded pair's header may carry the robot head's joints at its capture (flag bit 1
// of video::EncodedFrameHeader), which a version-6 station would refuse as bad flags.
inline constexpr std::uint8_t kProtocolVersion = 7;
inline constexpr std::size_t kHeaderSize = 36;
// Default bound on one message (header + payload). A 640x480 raw frame is 614400 bytes.
inline constexpr std::size_t kDefaultMaxMessageBytes = 1u << 20;

// Wire values are fixed; the std::variant Message below lists the payloads in this order.
enum class MsgType : std::uint8_t {
  Hello = 0,
  Accept = 1,
  Reject = 2,
  Heartbeat = 3,
  Bye = 4,
  StreamConfig = 5,
  DepthTile = 6,
  FrameManifest = 7,
  EncodedVideo = 8,
  RoiRequest = 9,
  Stats = 10,
  TileNack = 11,
  HeadCommand = 12,
  PictureLoss = 13,
  ReceiverReport = 14,
  VideoNack = 15,
};
inline constexpr int kMsgTypeCount = 16;
std::string_view msg_type_name(MsgType type);

// Header flag bits.
inline constexpr std::uint16_t kFlagKeyFrame =
    1u << 0;  // the frame this message belongs to is a key frame
// Bit 1 is reserved: version 3 marked an HMAC tag with it; version 4 protects the link with TLS
// and sealed datagrams instead (tls.h, seal.h), below the messages.
// The message belongs to the ROI part of its frame: a second FrameManifest with the same frame id
// (without this flag) follows and closes the frame (PROTOCOL.md 2.4).
inline constexpr std::uint16_t kFlagRoiPart = 1u << 2;
// A DepthTile resent in answer to a TileNack (PROTOCOL.md 2.5): the tile as it was encoded for
// the header's frame_id, outside that frame's manifest.
inline constexpr std::uint16_t kFlagRepair = 1u << 3;

struct Header {
  std::uint32_t magic = kMagic;
  std::uint8_t version = kProtocolVersion;
  MsgType type = MsgType::Hello;  // encode() overwrites it from the payload
  std::uint16_t flags = 0;
  std::uint32_t session_id = 0;
  std::uint32_t seq = 0;       // per-sender message counter (loss and reorder detection)
  std::uint32_t frame_id = 0;  // depth/video frame the message belongs to (0 when none)
  std::uint64_t capture_ns = 0;
  std::uint32_t payload_len = 0;  // encode() fills it
  std::uint32_t crc32c = 0;  // encode() fills it: over the header with this field zero + payload
  bool operator==(const Header&) const = default;
};

// Capability bits announced in Hello.
inline constexpr std::uint32_t kCapDepthTcp = 1u << 0;
inline constexpr std::uint32_t kCapDepthUdp = 1u << 1;
inline constexpr std::uint32_t kCapVideo = 1u << 2;
inline constexpr std::uint32_t kCapRoi = 1u << 3;
inline constexpr std::uint32_t kCapStats = 1u << 4;
// The client takes a frame in two parts (ROI tiles first, then the rest; PROTOCOL.md 2.4).
inline constexpr std::uint32_t kCapFrameParts = 1u << 5;
// The client sends TileNack and takes repaired tiles (kFlagRepair; PROTOCOL.md 2.5).
inline constexpr std::uint32_t kCapRepair = 1u << 6;

enum class Transport : std::uint8_t { Tcp = 0, Udp = 1 };

// Bounds enforced by decode (and by encode, which throws std::invalid_argument past them).
inline constexpr std::size_t kMaxHelloCodecs = 16;
inline constexpr std::size_t kMaxText = 1024;
inline constexpr std::size_t kMaxRoiRects = 16;
inline constexpr std::size_t kMaxStatsEntries = 64;
inline constexpr std::size_t kMaxStatsKey = 64;
inline constexpr std::size_t kMaxManifestTiles = 4096;

struct Hello {
  std::uint8_t version = kProtocolVersion;
  std::uint32_t capabilities = 0;
  std::vector<Codec> codecs;   // in order of preference
  std::uint16_t udp_port = 0;  // where the sender receives UDP (0 = none)
  bool operator==(const Hello&) const = default;
};

struct Accept {
  std::uint32_t session_id = 0;
  Codec codec = Codec::Zip;
  Transport transport = Transport::Tcp;
  std::uint16_t udp_port = 0;  // the accepting side's UDP port (0 = none)
  bool operator==(const Accept&) const = default;
};

enum class RejectReason : std::uint16_t {
  Unspecified = 0,
  VersionMismatch = 1,
  NoCommonCodec = 2,
  Busy = 3,
  BadRequest = 4,
  AuthFailed = 5,  // the Hello did not authenticate under the server's pre-shared key
};

struct Reject {
  RejectReason reason = RejectReason::Unspecified;
  std::string text;  // UTF-8, at most kMaxText bytes
  bool operator==(const Reject&) const = default;
};

// NTP-style round trip: t1 sent (client clock), t2 received and t3 answered (server clock),
// t4 received (client clock; 0 on the wire when not yet known). Offset and delay follow RFC 5905.
struct Heartbeat {
  std::uint64_t t1_ns = 0;
  std::uint64_t t2_ns = 0;
  std::uint64_t t3_ns = 0;
  std::uint64_t t4_ns = 0;
  bool operator==(const Heartbeat&) const = default;
};

struct Bye {
  std::uint16_t reason = 0;  // 0 = normal shutdown
  bool operator==(const Bye&) const = default;
};

// How the depth map was brought into the right-eye camera: a 3-D translation of the depth camera
// relative to the eye and the 2-D scale/shift applied to the image (identity when unregistered).
struct RegistrationParams {
  std::array<double, 3> t_eye_depth_m{0.0, 0.0, 0.0};
  double scale_x = 1.0;
  double scale_y = 1.0;
  double shift_x_px = 0.0;
  double shift_y_px = 0.0;
  bool operator==(const RegistrationParams&) const = default;
};

struct StreamConfig {
  std::uint16_t width = 640;
  std::uint16_t height = 480;
  double fx = 525.0, fy = 525.0, cx = 319.5, cy = 239.5;  // of the depth as sent (pixels)
  RegistrationParams registration;
  std::uint16_t tile_width = 80;
  std::uint16_t tile_height = 60;
  std::uint16_t grid_cols = 8;  // must equal ceil(width / tile_width)
  std::uint16_t grid_rows = 8;  // must equal ceil(height / tile_height)
  Codec codec = Codec::Zip;
  float fps = 30.0f;
  bool operator==(const StreamConfig&) const = default;
};

struct DepthTile {
  std::uint16_t tile_index = 0;
  std::uint16_t x = 0, y = 0, w = 0, h = 0;  // pixel rectangle in the frame
  Codec codec = Codec::Zip;
  std::vector<std::uint8_t> payload;  // codec bitstream of exactly w*h pixels
  bool operator==(const DepthTile&) const = default;
};

// The message that carries one encoded tile (what the remote sends for each tile of a frame).
inline DepthTile tile_message(const EncodedTile& t, Codec codec) {
  return DepthTile{t.index,
                   static_cast<std::uint16_t>(t.rect.x),
                   static_cast<std::uint16_t>(t.rect.y),
                   static_cast<std::uint16_t>(t.rect.width),
                   static_cast<std::uint16_t>(t.rect.height),
                   codec,
                   t.bytes};
}

// The robot head's joints (yaw, pitch, roll in radians; docs/RIG.md robot_head) as measured.
struct HeadJoints {
  bool valid = false;  // false: no head, or no reading (the station then uses its own head pose)
  std::array<float, 3> joint_rad{0.0f, 0.0f, 0.0f};
  bool operator==(const HeadJoints&) const = default;
};

struct FrameManifest {
  std::uint32_t frame_id = 0;
  std::uint16_t tile_count = 0;              // tiles in the grid
  bool key_frame = false;                    // all tiles sent; otherwise only `changed_tiles`
  std::vector<std::uint16_t> changed_tiles;  // strictly increasing, each < tile_count
  HeadJoints head;                           // the robot head at the frame's capture time
  bool operator==(const FrameManifest&) const = default;
};

// One encoded stereo pair (remote -> station, fragmented and sealed like depth): the bytes
// video::EyeEncoder wrote, a video::EncodedFrameHeader (30 bytes, 42 with the robot head's joints
// at capture) then exactly its payload_bytes of H.264 or MJPEG. decode() checks them with
// video::parse_frame (geometry, codec, lengths).
struct EncodedVideo {
  std::vector<std::uint8_t> frame;
  bool operator==(const EncodedVideo&) const = default;
};

// Why the station asks for an intra pair (PROTOCOL.md 2.7). Wire values; never renumber.
enum class PictureLossReason : std::uint8_t {
  MissingReference = 0,  // a pair was lost (encode_seq gap, or it never completed in time)
  DecodeError = 1,       // the decoder refused a pair
};
inline constexpr std::uint8_t kMaxPictureLossReason = 1;

// Picture Loss Indication (RFC 4585 6.3.1; station -> remote): the eyes' decoder lacks a
// reference; the remote's encoder makes its next pair intra.
struct PictureLoss {
  std::uint32_t last_good_seq = 0;  // encode_seq of the last pair decoded whole (0 when none)
  PictureLossReason reason = PictureLossReason::MissingReference;
  bool operator==(const PictureLoss&) const = default;
};

// Bounds of ReceiverReport (decode rejects values beyond them).
inline constexpr std::uint32_t kMaxReportIntervalUs = 10'000'000;
inline constexpr std::int32_t kMaxReportDelayUs = 60'000'000;

// What the station received over UDP in the last interval (station -> remote, every heartbeat):
// the input of a delay- and loss-based rate controller (WebRTC's GCC). Delays are one-way, from
// capture (the message header's capture_ns, remote clock) to the whole message's arrival (station
// clock moved to the remote's by the heartbeat offset): their level carries the clock estimate's
// error and the remote's processing; their change (the gradient) is what a controller reads.
struct ReceiverReport {
  std::uint32_t interval_us = 0;     // 1..kMaxReportIntervalUs: time the counts cover
  std::uint64_t bytes_received = 0;  // datagram bytes (depth and video) in the interval
  std::uint64_t video_bytes = 0;     // of them, whole EncodedVideo messages
  std::uint32_t datagrams_received = 0;
  std::uint32_t fragments_lost = 0;   // ReassemblerCounters::lost() in the interval
  std::uint32_t delay_samples = 0;    // whole messages the delays below are over (0: all 0)
  std::int32_t delay_mean_us = 0;     // |.| <= kMaxReportDelayUs
  std::int32_t delay_last_us = 0;     //
  float delay_gradient_us_per_s = 0;  // least-squares slope of delay over arrival time; finite
  bool operator==(const ReceiverReport&) const = default;
};

// Most pairs one VideoNack asks for (a longer gap is a lost cause: a PLI is cheaper).
inline constexpr std::uint16_t kMaxVideoNackPairs = 16;

// A NACK of whole encoded pairs (station -> remote, PROTOCOL.md 2.7): the pairs with encode_seq
// first_seq .. first_seq + count - 1 never completed at the station; the remote sends each again
// (kFlagRepair) if it still holds it, within its repair budget.
struct VideoNack {
  std::uint32_t first_seq = 0;
  std::uint16_t count = 1;  // 1..kMaxVideoNackPairs
  bool operator==(const VideoNack&) const = default;
};

struct RoiRect {
  std::uint16_t x = 0, y = 0, w = 0, h = 0;
  std::uint8_t priority = 0;  // higher = sooner
  bool operator==(const RoiRect&) const = default;
};

struct RoiRequest {
  std::vector<RoiRect> rects;  // at most kMaxRoiRects
  bool operator==(const RoiRequest&) const = default;
};

struct Stats {
  std::vector<std::pair<std::string, std::uint64_t>> counters;  // keys ASCII, <= kMaxStatsKey
  bool operator==(const Stats&) const = default;
};

// A generic NACK (RFC 4585 section 6.2.1, by tile instead of by packet): the tiles of frame
// `frame_id` (or of any newer frame that changed them) that the client needs and lacks.
struct TileNack {
  std::uint32_t frame_id = 0;
  std::vector<std::uint16_t> tiles;  // 1..kMaxManifestTiles, strictly increasing
  bool operator==(const TileNack&) const = default;
};

// The operator's dead-man input (PROTOCOL.md 2.6): wire values, anything else is BadPayload.
enum class DeadmanState : std::uint8_t {
  NotUsed = 0,   // the station has no dead-man input
  Pressed = 1,   // held: the head may move
  Released = 2,  // let go, or the device failed: the head holds still
};
inline constexpr std::uint8_t kMaxDeadmanState = 2;

// The operator's head as robot head joint targets (station -> remote, at 100 Hz or more): the
// remote clamps them to its limits, rate- and acceleration-limits them and drives the head, and
// holds the head still when the tracking sample is stale or repeats, or the dead-man is released
// (PROTOCOL.md 2.6).
struct HeadCommand {
  std::uint64_t operator_ns = 0;  // when the operator's head was at this pose (client clock)
  std::array<float, 3> joint_rad{0.0f, 0.0f, 0.0f};  // yaw, pitch, roll; finite, |angle| <= pi
  std::uint32_t sample_id = 0;      // the client's count of tracking samples: a repeat is the same
  std::uint32_t sample_age_us = 0;  // the sample's age when sent, us (saturates at 2^32 - 1)
  DeadmanState deadman = DeadmanState::NotUsed;
  bool operator==(const HeadCommand&) const = default;
};

// Alternative index == MsgType wire value.
using Message = std::variant<Hello, Accept, Reject, Heartbeat, Bye, StreamConfig, DepthTile,
                             FrameManifest, EncodedVideo, RoiRequest, Stats, TileNack, HeadCommand,
                             PictureLoss, ReceiverReport, VideoNack>;

MsgType type_of(const Message& message);

// Why bytes were rejected. Values index the drop counters; never renumber.
enum class ErrorReason : std::uint8_t {
  Truncated = 0,      // fewer bytes than the header or a length field claims
  BadMagic,           // not "TLX1"
  BadVersion,         // header version this build does not speak
  BadLength,          // a length beyond the configured bound or inconsistent with the framing
  BadChecksum,        // CRC32C mismatch
  UnknownType,        // message type not in MsgType
  BadTileGeometry,    // tile rectangle empty, outside the frame or inconsistent with the grid
  DecompressionBomb,  // a tile claims more pixels than allowed
  BadPayload,         // payload shape wrong (counts, enum values, trailing bytes)
  AuthFailed,         // a sealed datagram that does not open (another key, or bits changed)
  Unsealed,           // a datagram without the seal (seal.h) while the link is sealed
  Replayed,  // a sealed datagram whose sequence number was seen or is older than the window
};
inline constexpr int kErrorReasonCount = 12;
std::string_view error_reason_name(ErrorReason reason);

// Validation bounds for decoding. frame_width/height (0 = unknown) come from StreamConfig and make
// tile rectangles checkable against the frame.
struct DecodeLimits {
  std::size_t max_message_bytes = kDefaultMaxMessageBytes;
  std::uint32_t max_tile_pixels = 640u * 480u;
  std::uint16_t frame_width = 0;
  std::uint16_t frame_height = 0;
};

struct Envelope {
  Header header;
  Message message;
};

// Outcome of decoding one message: the message, or the reason and a static detail string.
struct Result {
  std::optional<Envelope> envelope;
  ErrorReason error = ErrorReason::Truncated;  // meaningful only when !ok()
  const char* detail = "";
  bool ok() const { return envelope.has_value(); }
};

// Header + payload, ready for a datagram or the reassembler. Header type, payload_len and crc32c
// are computed; magic and version are written as given. Throws std::invalid_argument when a
// field is beyond the bounds above (a sender bug, not wire input).
std::vector<std::uint8_t> encode(const Header& header, const Message& message);
// The same prefixed with the u32 little-endian length of what follows: the TCP stream framing.
std::vector<std::uint8_t> encode_stream(const Header& header, const Message& message);

struct Error {
  ErrorReason reason;
  const char* detail;  // static string naming the field
};
// Parses and validates the 36-byte header (magic, version, type, length bound); no CRC check.
std::optional<Error> decode_header(std::span<const std::uint8_t> bytes, Header& out,
                                   const DecodeLimits& limits = {});
// Decodes one whole message (header + payload, no length prefix), checking everything.
Result decode(std::span<const std::uint8_t> bytes, const DecodeLimits& limits = {});

}  // namespace telex::proto
