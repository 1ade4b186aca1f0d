// SPDX-License-Identifier: MIT
// The encoded pair's header: round trip, and every malformed input refused with its reason.
#include "telex/video/frame_header.h"

#include <gtest/gtest.h>

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
  EXPECT_EQ(with(4, 0x02), HeaderStatus::BadFlags);
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

TEST(FrameHeader, PayloadLengthBoundedBeforeItIsRead) {
  // A header claiming more than the maximum is refused as such, whatever follows it.
  EncodedFrameHeader h = sample(static_cast<std::uint32_t>(kMaxPayloadBytes + 1));
  EXPECT_EQ(parse_frame(frame_bytes(h, Bytes(16, 0))).status, HeaderStatus::PayloadTooLong);
  h.payload_bytes = 0xffffffffu;
  EXPECT_EQ(parse_frame(frame_bytes(h, {})).status, HeaderStatus::PayloadTooLong);
}

}  // namespace
}  // namespace telex::video
