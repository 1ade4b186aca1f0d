// SPDX-License-Identifier: MIT
// The eyes' messages (docs/PROTOCOL.md 2.7): exact layouts, round trips, and every malformed
// input rejected with its reason and counted by the parsers.
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <limits>

#include "proto_samples.h"
#include "telex/proto/crc32c.h"
#include "telex/proto/messages.h"
#include "telex/proto/parser.h"

namespace telex::proto {
namespace {

// The payload's bytes of `m` (after the 36-byte header).
std::vector<std::uint8_t> payload_of(const Message& m) {
  const auto b = encode({}, m);
  return {b.begin() + kHeaderSize, b.end()};
}

// A whole message with `payload` as the payload of `type`, CRC correct.
std::vector<std::uint8_t> message_with(MsgType type, const std::vector<std::uint8_t>& payload) {
  auto b = encode({}, Bye{});
  b.resize(kHeaderSize);
  b[5] = static_cast<std::uint8_t>(type);
  b.insert(b.end(), payload.begin(), payload.end());
  const auto n = static_cast<std::uint32_t>(payload.size());
  for (int i = 0; i < 4; ++i) b[28 + i] = static_cast<std::uint8_t>(n >> (8 * i));
  for (int i = 0; i < 4; ++i) b[32 + i] = 0;
  const std::uint32_t crc = crc32c(b);
  for (int i = 0; i < 4; ++i) b[32 + i] = static_cast<std::uint8_t>(crc >> (8 * i));
  return b;
}

TEST(VideoMessages, EncodedVideoCarriesThePairByteForByte) {
  const auto pair = test::encoded_pair(9);
  EXPECT_EQ(payload_of(EncodedVideo{pair}), pair);
  const auto r = decode(encode(test::sample_header(), EncodedVideo{pair}));
  ASSERT_TRUE(r.ok()) << r.detail;
  EXPECT_EQ(std::get<EncodedVideo>(r.envelope->message).frame, pair);
  EXPECT_EQ(msg_type_name(MsgType::EncodedVideo), "EncodedVideo");
}

// Since version 7 a pair's header may carry the robot head's joints at its capture (PROTOCOL.md
// 2.7): they cross the wire unchanged, and a pair without them (the old layout) still decodes and
// says it has none.
TEST(VideoMessages, EncodedVideoCarriesTheHeadPoseAndAPairWithoutOneStillDecodes) {
  EXPECT_EQ(kProtocolVersion, 7);
  const std::array<float, 3> joints{0.4f, -0.2f, 0.05f};
  const auto posed = test::encoded_pair(9, joints);
  ASSERT_EQ(posed.size(), video::kHeaderBytes + video::kHeadPoseBytes + 9);
  const auto r = decode(encode(test::sample_header(), EncodedVideo{posed}));
  ASSERT_TRUE(r.ok()) << r.detail;
  const auto& frame = std::get<EncodedVideo>(r.envelope->message).frame;
  EXPECT_EQ(frame, posed);
  const video::ParsedFrame parsed = video::parse_frame(frame);
  ASSERT_EQ(parsed.status, video::HeaderStatus::Ok);
  ASSERT_TRUE(parsed.header.head_joint_rad.has_value());
  EXPECT_EQ(*parsed.header.head_joint_rad, joints);
  EXPECT_EQ(parsed.payload.size(), 9u);

  const auto plain = test::encoded_pair(9);
  ASSERT_EQ(plain.size(), video::kHeaderBytes + 9);
  const auto old = decode(encode(test::sample_header(), EncodedVideo{plain}));
  ASSERT_TRUE(old.ok()) << old.detail;
  EXPECT_FALSE(video::parse_frame(std::get<EncodedVideo>(old.envelope->message).frame)
                   .header.head_joint_rad.has_value());
}

TEST(VideoMessages, PictureLossAndReceiverReportLayouts) {
  EXPECT_EQ(payload_of(PictureLoss{0x01020304, PictureLossReason::DecodeError}),
            (std::vector<std::uint8_t>{4, 3, 2, 1, 1}));
  const ReceiverReport rr{250'000, 9, 4, 3, 2, 1, -5, 6, 0.5f};
  const auto p = payload_of(rr);
  ASSERT_EQ(p.size(), 44u);
  EXPECT_EQ(p[0], 0x90);   // 250000 = 0x03D090
  EXPECT_EQ(p[4], 9);      // bytes_received
  EXPECT_EQ(p[12], 4);     // video_bytes
  EXPECT_EQ(p[20], 3);     // datagrams
  EXPECT_EQ(p[24], 2);     // fragments lost
  EXPECT_EQ(p[28], 1);     // delay samples
  EXPECT_EQ(p[32], 0xFB);  // -5, two's complement
  EXPECT_EQ(p[35], 0xFF);
  EXPECT_EQ(p[36], 6);
  EXPECT_EQ(std::bit_cast<float>(std::uint32_t{p[40]} | std::uint32_t{p[41]} << 8 |
                                 std::uint32_t{p[42]} << 16 | std::uint32_t{p[43]} << 24),
            0.5f);
  EXPECT_EQ(payload_of(VideoNack{0x0A0B0C0D, 3}),
            (std::vector<std::uint8_t>{0x0D, 0x0C, 0x0B, 0x0A, 3, 0}));
  for (const Message& m : {Message{PictureLoss{7, PictureLossReason::MissingReference}},
                           Message{rr}, Message{ReceiverReport{1, 0, 0, 0, 0, 0, 0, 0, 0.0f}},
                           Message{VideoNack{0xFFFFFFFF, 16}}}) {
    const auto r = decode(encode(test::sample_header(), m));
    ASSERT_TRUE(r.ok()) << r.detail;
    EXPECT_EQ(r.envelope->message, m);
  }
}

struct Malformed {
  const char* name;
  MsgType type;
  std::vector<std::uint8_t> payload;
  ErrorReason reason;
};

std::vector<Malformed> malformed_inputs() {
  std::vector<Malformed> out;
  auto pair = test::encoded_pair(9);
  out.push_back({"video: header only part",
                 MsgType::EncodedVideo,
                 {pair.begin(), pair.begin() + 20},
                 ErrorReason::Truncated});
  out.push_back({"video: payload cut",
                 MsgType::EncodedVideo,
                 {pair.begin(), pair.end() - 1},
                 ErrorReason::Truncated});
  auto longer = pair;
  longer.push_back(0);
  out.push_back({"video: trailing byte", MsgType::EncodedVideo, longer, ErrorReason::BadPayload});
  auto magic = pair;
  magic[0] = 'X';
  out.push_back({"video: magic", MsgType::EncodedVideo, magic, ErrorReason::BadPayload});
  auto codec = pair;
  codec[3] = 9;
  out.push_back({"video: codec", MsgType::EncodedVideo, codec, ErrorReason::BadPayload});
  auto odd = pair;
  odd[6] = 63;  // an odd H.264 eye width
  out.push_back({"video: odd width", MsgType::EncodedVideo, odd, ErrorReason::BadTileGeometry});
  auto huge = pair;
  huge[29] = 0x7F;  // payload_bytes far above 32 MiB
  out.push_back(
      {"video: huge payload", MsgType::EncodedVideo, huge, ErrorReason::DecompressionBomb});
  auto posed = test::encoded_pair(9, std::array<float, 3>{0.1f, 0.2f, 0.3f});
  out.push_back({"video: head pose cut",
                 MsgType::EncodedVideo,
                 {posed.begin(), posed.begin() + 36},
                 ErrorReason::Truncated});
  auto beyond_pi = posed;
  beyond_pi[33] = 0x7F;  // yaw's top byte (bytes 30..33): 0x7FCCCCCD is not a number
  out.push_back({"video: head pose", MsgType::EncodedVideo, beyond_pi, ErrorReason::BadPayload});
  auto flags = pair;
  flags[4] |= 0x04;
  out.push_back({"video: unknown flag", MsgType::EncodedVideo, flags, ErrorReason::BadPayload});
  out.push_back({"pli: short", MsgType::PictureLoss, {1, 0, 0}, ErrorReason::Truncated});
  out.push_back({"pli: reason", MsgType::PictureLoss, {1, 0, 0, 0, 2}, ErrorReason::BadPayload});
  out.push_back({"video nack: short", MsgType::VideoNack, {1, 0, 0, 0, 1}, ErrorReason::Truncated});
  out.push_back(
      {"video nack: count 0", MsgType::VideoNack, {1, 0, 0, 0, 0, 0}, ErrorReason::BadPayload});
  out.push_back(
      {"video nack: count 17", MsgType::VideoNack, {1, 0, 0, 0, 17, 0}, ErrorReason::BadPayload});
  const auto report = [](ReceiverReport r) { return payload_of(r); };
  const ReceiverReport good{250'000, 100, 50, 3, 0, 2, 1000, 1100, 3.0f};
  auto rr = report(good);
  out.push_back({"report: short",
                 MsgType::ReceiverReport,
                 {rr.begin(), rr.end() - 1},
                 ErrorReason::Truncated});
  auto zero_interval = rr;
  std::fill(zero_interval.begin(), zero_interval.begin() + 4, 0);
  out.push_back(
      {"report: interval 0", MsgType::ReceiverReport, zero_interval, ErrorReason::BadPayload});
  auto video_above = rr;
  video_above[12] = 200;  // video_bytes 200 > bytes_received 100
  out.push_back(
      {"report: video above all", MsgType::ReceiverReport, video_above, ErrorReason::BadPayload});
  auto far = rr;
  far[35] = 0x7F;  // delay_mean far beyond 60 s
  out.push_back({"report: delay", MsgType::ReceiverReport, far, ErrorReason::BadPayload});
  auto nan = rr;
  nan[40] = nan[41] = 0xFF;
  nan[42] = 0xC0;
  nan[43] = 0x7F;
  out.push_back({"report: NaN gradient", MsgType::ReceiverReport, nan, ErrorReason::BadPayload});
  auto no_samples = rr;
  std::fill(no_samples.begin() + 28, no_samples.begin() + 32, 0);
  out.push_back({"report: delays without samples", MsgType::ReceiverReport, no_samples,
                 ErrorReason::BadPayload});
  return out;
}

TEST(VideoMessages, MalformedInputIsRejectedWithItsReasonAndCounted) {
  DatagramParser datagrams;
  std::uint64_t expected = 0;
  for (const auto& m : malformed_inputs()) {
    const auto bytes = message_with(m.type, m.payload);
    const auto r = decode(bytes);
    ASSERT_FALSE(r.ok()) << m.name;
    EXPECT_EQ(r.error, m.reason) << m.name << ": " << error_reason_name(r.error) << " " << r.detail;
    EXPECT_FALSE(datagrams.parse(bytes).ok()) << m.name;
    EXPECT_EQ(datagrams.drops().total(), expected + 1) << m.name;
    ++expected;
    // On TCP the stream parser counts it too; a bad payload is skipped and parsing goes on, a
    // truncated one means the framing cannot be trusted (the caller closes).
    StreamParser stream;
    std::vector<std::uint8_t> framed{static_cast<std::uint8_t>(bytes.size()),
                                     static_cast<std::uint8_t>(bytes.size() >> 8), 0, 0};
    framed.insert(framed.end(), bytes.begin(), bytes.end());
    EXPECT_EQ(stream.feed(framed), framed.size()) << m.name;
    const auto s = stream.next();
    ASSERT_TRUE(s.has_value()) << m.name;
    EXPECT_EQ(s->error, m.reason) << m.name;
    EXPECT_EQ(stream.drops().of(m.reason), 1u) << m.name;
    EXPECT_EQ(stream.failed(), m.reason == ErrorReason::Truncated) << m.name;
  }
  EXPECT_EQ(datagrams.drops().total(), expected);
  EXPECT_EQ(datagrams.messages(), 0u);
}

TEST(VideoMessages, EncodeRefusesWhatDecodeWouldReject) {
  auto pair = test::encoded_pair(9);
  pair.pop_back();
  EXPECT_THROW(encode({}, EncodedVideo{pair}), std::invalid_argument);
  EXPECT_THROW(encode({}, PictureLoss{1, static_cast<PictureLossReason>(5)}),
               std::invalid_argument);
  EXPECT_THROW(encode({}, ReceiverReport{0, 0, 0, 0, 0, 0, 0, 0, 0.0f}), std::invalid_argument);
  EXPECT_THROW(encode({}, VideoNack{1, 0}), std::invalid_argument);
  EXPECT_THROW(encode({}, VideoNack{1, kMaxVideoNackPairs + 1}), std::invalid_argument);
  EXPECT_THROW(encode({}, ReceiverReport{1, 1, 2, 0, 0, 0, 0, 0, 0.0f}), std::invalid_argument);
  EXPECT_THROW(
      encode({}, ReceiverReport{1, 0, 0, 0, 0, 1, 0, 0, std::numeric_limits<float>::infinity()}),
      std::invalid_argument);
}

}  // namespace
}  // namespace telex::proto
