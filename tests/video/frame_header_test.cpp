// SPDX-License-Identifier: MIT
// The encoded pair's header: round trip, and every malformed input refused with its reason.
#include "telex/video/frame_header.h"

#include <gtest/gtest.h>

#include <array>
#include <limits>
#include <span>
#include <vector>

namespace telex::video {
namespace {

using Bytes = std::vector<std::uint8_t>;

EncodedFrameHeader sample(std::uint32_t payload_bytes) {
  EncodedFrameHeader h;
  h.frame_id = 0x01020304;
  h.encode_seq = 77;
  h.capture_ns = -5;  // any clock: negative values survive too
  h.codec = VideoCodec::Mjpeg;
  h.is_intra = true;
  h.eye_width_px = 1280;
  h.eye_height_px = 720;
  h.payload_bytes = payload_bytes;
  return h;
}

Bytes frame_bytes(const EncodedFrameHeader& h, const Bytes& payload) {
  Bytes b;
  serialize_header(h, b);
  b.insert(b.end(), payload.begin(), payload.end());
  return b;
}

TEST(FrameHeader, RoundTripsEveryField) {
  const Bytes payload{1, 2, 3, 4, 5};
  const Bytes bytes = frame_bytes(sample(5), payload);
  ASSERT_EQ(bytes.size(), kHeaderBytes + payload.size());
  const ParsedFrame p = parse_frame(bytes);
  ASSERT_EQ(p.status, HeaderStatus::Ok) << header_status_name(p.status);
  EXPECT_EQ(p.header.frame_id, 0x01020304u);
  EXPECT_EQ(p.header.encode_seq, 77u);
  EXPECT_EQ(p.header.capture_ns, -5);
  EXPECT_EQ(p.header.codec, VideoCodec::Mjpeg);
  EXPECT_TRUE(p.header.is_intra);
  EXPECT_EQ(p.header.eye_width_px, 1280);
  EXPECT_EQ(p.header.eye_height_px, 720);
  EXPECT_EQ(Bytes(p.payload.begin(), p.payload.end()), payload);
}

TEST(FrameHeader, EveryTruncationIsTruncated) {
  const Bytes bytes = frame_bytes(sample(6), Bytes(6, 9));
  for (std::size_t n = 0; n < bytes.size(); ++n) {
    const ParsedFrame p = parse_frame(std::span(bytes).first(n));
    EXPECT_EQ(p.status, HeaderStatus::Truncated) << "length " << n;
    EXPECT_TRUE(p.payload.empty());
  }
}

TEST(FrameHeader, TrailingBytesRefused) {
  Bytes bytes = frame_bytes(sample(2), Bytes(2, 1));
  bytes.push_back(0);
  EXPECT_EQ(parse_frame(bytes).status, HeaderStatus::TrailingBytes);
}

TEST(FrameHeader, BadFieldsRefusedWithTheirReason) {
  const Bytes good = frame_bytes(sample(0), {});
  const auto with = [&](std::size_t offset, std::uint8_t value) {
    Bytes b = good;
    b[offset] = value;
    return parse_frame(b).status;
  };
  EXPECT_EQ(with(0, 'X'), HeaderStatus::BadMagic);
  EXPECT_EQ(with(1, 'X'), HeaderStatus::BadMagic);
  EXPECT_EQ(with(2, kHeaderVersion + 1), HeaderStatus::BadMagic);
  EXPECT_EQ(with(3, 0), HeaderStatus::UnknownCodec);
  EXPECT_EQ(with(3, 3), HeaderStatus::UnknownCodec);
  EXPECT_EQ(with(4, 0x04), HeaderStatus::BadFlags);
  EXPECT_EQ(with(4, 0x80), HeaderStatus::BadFlags);
  // Bit 1 says a head pose follows: a frame too short for it is truncated.
  EXPECT_EQ(with(4, 0x02), HeaderStatus::Truncated);
  EXPECT_EQ(with(5, 1), HeaderStatus::BadFlags);
}

TEST(FrameHeader, GeometryBounded) {
  for (const auto& [w, h, codec, ok] :
       {std::tuple{0, 720, VideoCodec::Mjpeg, false}, std::tuple{1280, 0, VideoCodec::H264, false},
        std::tuple{kMaxEyeSidePx + 2, 720, VideoCodec::H264, false},
        std::tuple{1281, 720, VideoCodec::H264, false},  // odd: not 4:2:0
        std::tuple{1281, 721, VideoCodec::Mjpeg, true},
        std::tuple{kMaxEyeSidePx, kMaxEyeSidePx, VideoCodec::H264, true}}) {
    EncodedFrameHeader hd = sample(0);
    hd.eye_width_px = static_cast<std::uint16_t>(w);
    hd.eye_height_px = static_cast<std::uint16_t>(h);
    hd.codec = codec;
    EXPECT_EQ(parse_frame(frame_bytes(hd, {})).status,
              ok ? HeaderStatus::Ok : HeaderStatus::BadGeometry)
        << w << "x" << h << " " << video_codec_name(codec);
  }
}

// The robot head's joints at capture: flag bit 1 and three f32 between the header and the payload.
TEST(FrameHeader, HeadPoseRoundTripsBetweenHeaderAndPayload) {
  EncodedFrameHeader h = sample(3);
  h.head_joint_rad = std::array<float, 3>{0.5f, -0.25f, 3.14159f};
  const Bytes bytes = frame_bytes(h, {7, 8, 9});
  ASSERT_EQ(header_bytes(h), kHeaderBytes + kHeadPoseBytes);
  ASSERT_EQ(bytes.size(), kHeaderBytes + kHeadPoseBytes + 3);
  EXPECT_EQ(bytes[4], 0x03);  // intra | head pose
  const ParsedFrame p = parse_frame(bytes);
  ASSERT_EQ(p.status, HeaderStatus::Ok) << header_status_name(p.status);
  EXPECT_EQ(p.header, h);
  EXPECT_EQ(Bytes(p.payload.begin(), p.payload.end()), (Bytes{7, 8, 9}));
  for (std::size_t n = kHeaderBytes; n < kHeaderBytes + kHeadPoseBytes; ++n)
    EXPECT_EQ(parse_frame(std::span(bytes).first(n)).status, HeaderStatus::Truncated) << n;
}

// A frame without a pose is byte for byte what the header was before poses: it still parses, and
// says it has none; stamping one in afterwards gives what serializing it with one gives.
TEST(FrameHeader, AnOldFrameWithoutAPoseParsesAndCanBeStamped) {
  const EncodedFrameHeader h = sample(4);
  Bytes bytes = frame_bytes(h, {1, 2, 3, 4});
  ASSERT_EQ(bytes.size(), kHeaderBytes + 4);
  EXPECT_EQ(bytes[4], 0x01);  // intra only
  const ParsedFrame old = parse_frame(bytes);
  ASSERT_EQ(old.status, HeaderStatus::Ok);
  EXPECT_FALSE(old.header.head_joint_rad.has_value());

  const std::array<float, 3> joints{-0.75f, 0.125f, 0.0f};
  ASSERT_TRUE(stamp_head_pose(bytes, joints));
  EncodedFrameHeader posed = h;
  posed.head_joint_rad = joints;
  EXPECT_EQ(bytes, frame_bytes(posed, {1, 2, 3, 4}));
  // Once only; and not into what does not parse.
  const Bytes stamped = bytes;
  EXPECT_FALSE(stamp_head_pose(bytes, joints));
  EXPECT_EQ(bytes, stamped);
  Bytes broken{1, 2, 3};
  EXPECT_FALSE(stamp_head_pose(broken, joints));
  EXPECT_EQ(broken, (Bytes{1, 2, 3}));
}

TEST(FrameHeader, HeadPoseBeyondPiOrNotFiniteRefused) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  for (const float bad : {3.2f, -3.2f, nan, inf}) {
    EncodedFrameHeader h = sample(0);
    h.head_joint_rad = std::array<float, 3>{0.0f, bad, 0.0f};
    EXPECT_EQ(parse_frame(frame_bytes(h, {})).status, HeaderStatus::BadHeadPose) << bad;
    EXPECT_FALSE(head_pose_fits(*h.head_joint_rad));
    Bytes plain = frame_bytes(sample(0), {});
    EXPECT_FALSE(stamp_head_pose(plain, *h.head_joint_rad));
  }
  EXPECT_TRUE(head_pose_fits({3.14159f, -3.14159f, 0.0f}));
}

TEST(FrameHeader, PayloadLengthBoundedBeforeItIsRead) {
  // A header claiming more than the maximum is refused as such, whatever follows it.
  EncodedFrameHeader h = sample(static_cast<std::uint32_t>(kMaxPayloadBytes + 1));
  EXPECT_EQ(parse_frame(frame_bytes(h, Bytes(16, 0))).status, HeaderStatus::PayloadTooLong);
  h.payload_bytes = 0xffffffffu;
  EXPECT_EQ(parse_frame(frame_bytes(h, {})).status, HeaderStatus::PayloadTooLong);
}

}  // namespace
}  // namespace telex::video
