// SPDX-License-Identifier: MIT
// Message encoding: exact byte layout, round trips of every type, and every rejection reason.
#include "telex/proto/messages.h"

#include <gtest/gtest.h>

#include <cstring>
#include <limits>

#include "proto_samples.h"
#include "telex/proto/crc32c.h"

namespace telex::proto {
namespace {

void put_u32(std::vector<std::uint8_t>& b, std::size_t off, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) b[off + i] = static_cast<std::uint8_t>(v >> (8 * i));
}

// Recomputes the CRC after a deliberate edit, so a test reaches the check behind it.
void reseal(std::vector<std::uint8_t>& b) {
  put_u32(b, 32, 0);
  put_u32(b, 32, crc32c(b));
}

TEST(Messages, HeaderLayoutIsLittleEndianFieldByField) {
  const auto bytes = encode(test::sample_header(), Bye{0x0A0B});
  ASSERT_EQ(bytes.size(), kHeaderSize + 2);
  const std::uint8_t expect[] = {'T',
                                 'L',
                                 'X',
                                 '1',                                      // magic
                                 kProtocolVersion,                         // version
                                 static_cast<std::uint8_t>(MsgType::Bye),  // type
                                 0x01,
                                 0x00,  // flags
                                 0x04,
                                 0x03,
                                 0x02,
                                 0x01,  // session
                                 9,
                                 0,
                                 0,
                                 0,  // seq
                                 77,
                                 0,
                                 0,
                                 0,  // frame id
                                 21,
                                 205,
                                 133,
                                 61,
                                 254,
                                 156,
                                 151,
                                 23,  // capture ns
                                 2,
                                 0,
                                 0,
                                 0};  // payload len
  ASSERT_EQ(std::memcmp(bytes.data(), expect, sizeof expect), 0);
  EXPECT_EQ(bytes[36], 0x0B);
  EXPECT_EQ(bytes[37], 0x0A);
  std::vector<std::uint8_t> zeroed = bytes;
  put_u32(zeroed, 32, 0);
  const std::uint32_t crc = crc32c(zeroed);
  EXPECT_EQ(
      bytes[32] | bytes[33] << 8 | bytes[34] << 16 | static_cast<std::uint32_t>(bytes[35]) << 24,
      crc);
}

TEST(Messages, EveryTypeRoundTrips) {
  for (const Message& m : test::sample_messages()) {
    const Header h = test::sample_header();
    const auto bytes = encode(h, m);
    const Result r = decode(bytes);
    ASSERT_TRUE(r.ok()) << msg_type_name(type_of(m)) << ": " << error_reason_name(r.error) << " "
                        << r.detail;
    EXPECT_EQ(r.envelope->message, m) << msg_type_name(type_of(m));
    EXPECT_EQ(r.envelope->header.type, type_of(m));
    EXPECT_EQ(r.envelope->header.seq, h.seq);
    EXPECT_EQ(r.envelope->header.capture_ns, h.capture_ns);
    EXPECT_EQ(r.envelope->header.payload_len, bytes.size() - kHeaderSize);
  }
}

TEST(Messages, StreamFramingPrefixesTheLength) {
  const auto s = encode_stream(test::sample_header(), Heartbeat{1, 2, 3, 4});
  const auto m = encode(test::sample_header(), Heartbeat{1, 2, 3, 4});
  ASSERT_EQ(s.size(), m.size() + 4);
  EXPECT_EQ(s[0] | s[1] << 8 | s[2] << 16 | s[3] << 24, static_cast<int>(m.size()));
  EXPECT_TRUE(std::equal(m.begin(), m.end(), s.begin() + 4));
}

TEST(Messages, EncodeRefusesOversizedFields) {
  Reject r{RejectReason::Busy, std::string(kMaxText + 1, 'x')};
  EXPECT_THROW(encode({}, r), std::invalid_argument);
  RoiRequest roi;
  roi.rects.resize(kMaxRoiRects + 1, RoiRect{0, 0, 1, 1, 0});
  EXPECT_THROW(encode({}, roi), std::invalid_argument);
}

Result decode_bytes(const std::vector<std::uint8_t>& b, DecodeLimits lim = {}) {
  return decode(b, lim);
}

TEST(Messages, RejectsTruncated) {
  auto b = encode(test::sample_header(), Heartbeat{1, 2, 3, 4});
  b.resize(20);
  EXPECT_EQ(decode_bytes(b).error, ErrorReason::Truncated);
  b = encode(test::sample_header(), Heartbeat{1, 2, 3, 4});
  b.pop_back();
  EXPECT_EQ(decode_bytes(b).error, ErrorReason::Truncated);
}

TEST(Messages, RejectsBadMagic) {
  auto b = encode(test::sample_header(), Bye{});
  b[0] = 'X';
  EXPECT_EQ(decode_bytes(b).error, ErrorReason::BadMagic);
}

TEST(Messages, RejectsBadVersion) {
  for (const std::uint8_t v :
       {std::uint8_t{kProtocolVersion - 1}, std::uint8_t{kProtocolVersion + 1}}) {
    auto b = encode(test::sample_header(), Bye{});
    b[4] = v;
    reseal(b);
    EXPECT_EQ(decode_bytes(b).error, ErrorReason::BadVersion) << int{v};
  }
}

TEST(Messages, RejectsBadLength) {
  auto b = encode(test::sample_header(), EncodedVideo{test::encoded_pair(100)});
  EXPECT_EQ(decode_bytes(b, {.max_message_bytes = 64}).error, ErrorReason::BadLength);
  b.push_back(0);  // a byte beyond payload_len
  EXPECT_EQ(decode_bytes(b).error, ErrorReason::BadLength);
}

TEST(Messages, RejectsBadChecksum) {
  auto b = encode(test::sample_header(), Heartbeat{1, 2, 3, 4});
  b[40] ^= 0x10;
  const Result r = decode_bytes(b);
  EXPECT_EQ(r.error, ErrorReason::BadChecksum);
  EXPECT_STRNE(r.detail, "");
}

TEST(Messages, RejectsUnknownType) {
  auto b = encode(test::sample_header(), Bye{});
  b[5] = kMsgTypeCount;
  reseal(b);
  EXPECT_EQ(decode_bytes(b).error, ErrorReason::UnknownType);
}

TEST(Messages, RejectsBadTileGeometry) {
  EXPECT_EQ(decode_bytes(encode({}, DepthTile{0, 0, 0, 0, 60, Codec::Zip, {1}})).error,
            ErrorReason::BadTileGeometry);
  DecodeLimits lim;
  lim.frame_width = 640;
  lim.frame_height = 480;
  EXPECT_EQ(decode_bytes(encode({}, DepthTile{0, 600, 0, 80, 60, Codec::Zip, {1}}), lim).error,
            ErrorReason::BadTileGeometry);
  EXPECT_TRUE(decode_bytes(encode({}, DepthTile{0, 560, 420, 80, 60, Codec::Zip, {1}}), lim).ok());
  StreamConfig sc;
  sc.grid_cols = 9;  // 640 / 80 is 8
  EXPECT_EQ(decode_bytes(encode({}, sc)).error, ErrorReason::BadTileGeometry);
  EXPECT_EQ(decode_bytes(encode({}, FrameManifest{1, 64, false, {64}, {}})).error,
            ErrorReason::BadTileGeometry);
}

TEST(Messages, RejectsDecompressionBomb) {
  // 4096 x 4096 pixels claimed by a few payload bytes.
  EXPECT_EQ(decode_bytes(encode({}, DepthTile{0, 0, 0, 4096, 4096, Codec::Zip, {1, 2}})).error,
            ErrorReason::DecompressionBomb);
  // Raw payload must be exactly w*h*2 bytes.
  EXPECT_EQ(decode_bytes(encode({}, DepthTile{0, 0, 0, 2, 2, Codec::Raw, {1, 2}})).error,
            ErrorReason::DecompressionBomb);
}

TEST(Messages, RejectsBadPayload) {
  auto b = encode({}, Accept{1, Codec::Zip, Transport::Tcp, 0});
  b[kHeaderSize + 4] = 9;  // codec
  reseal(b);
  EXPECT_EQ(decode_bytes(b).error, ErrorReason::BadPayload);
  EXPECT_EQ(decode_bytes(encode({}, FrameManifest{1, 64, false, {5, 5}, {}})).error,
            ErrorReason::BadPayload);
  EXPECT_EQ(decode_bytes(encode({}, Stats{{{"has space", 1}}})).error, ErrorReason::BadPayload);
  // A trailing byte inside payload_len that no field claims.
  b = encode({}, Bye{1});
  b.push_back(0);
  put_u32(b, 28, 3);
  reseal(b);
  EXPECT_EQ(decode_bytes(b).error, ErrorReason::BadPayload);
  // A short payload whose header length is consistent: the field reader runs out.
  b = encode({}, Heartbeat{});
  b.resize(kHeaderSize + 8);
  put_u32(b, 28, 8);
  reseal(b);
  EXPECT_EQ(decode_bytes(b).error, ErrorReason::Truncated);
}

}  // namespace
}  // namespace telex::proto

namespace telex::proto {
namespace {

// PROTOCOL.md 2.3: TileNack of frame 41, tiles 9, 10 and 17 is `29 00 00 00 · 03 00 · 09 00 0A 00
// 11 00` after the header, whose type byte is 11.
TEST(Messages, TileNackBytesAreTheDocumentedLayout) {
  const auto b = encode({}, TileNack{41, {9, 10, 17}});
  ASSERT_EQ(b.size(), kHeaderSize + 12);
  EXPECT_EQ(b[5], 11);
  const std::vector<std::uint8_t> payload(b.begin() + kHeaderSize, b.end());
  EXPECT_EQ(payload, (std::vector<std::uint8_t>{0x29, 0, 0, 0, 3, 0, 9, 0, 0x0A, 0, 0x11, 0}));
  const Result r = decode(b);
  ASSERT_TRUE(r.ok()) << r.detail;
  EXPECT_EQ(std::get<TileNack>(r.envelope->message), (TileNack{41, {9, 10, 17}}));
}

TEST(Messages, TileNackRejectsEmptyUnorderedAndShortLists) {
  EXPECT_THROW(encode({}, TileNack{1, {}}), std::invalid_argument);
  EXPECT_THROW(encode({}, TileNack{1, {4, 4}}), std::invalid_argument);
  auto b = encode({}, TileNack{1, {4, 5}});
  b[kHeaderSize + 8] = 4;  // the second index equals the first
  reseal(b);
  EXPECT_EQ(decode(b).error, ErrorReason::BadPayload);
  b = encode({}, TileNack{1, {4, 5}});
  b[kHeaderSize + 4] = 0;  // n = 0
  b.resize(kHeaderSize + 6);
  put_u32(b, 28, 6);
  reseal(b);
  EXPECT_EQ(decode(b).error, ErrorReason::BadPayload);
  b = encode({}, TileNack{1, {4, 5}});
  b[kHeaderSize + 4] = 3;  // claims a third index that is not there
  reseal(b);
  EXPECT_EQ(decode(b).error, ErrorReason::Truncated);
  b = encode({}, TileNack{1, {4, 5}});
  b[kHeaderSize + 9] = 0x10;  // index 4101 > 4095
  reseal(b);
  EXPECT_EQ(decode(b).error, ErrorReason::BadTileGeometry);
}

TEST(Messages, HeadCommandAndTheManifestsHeadJointsAreCheckedAngles) {
  // The layout: u64 operator time, yaw, pitch, roll as f32, u32 sample id, u32 sample age in us,
  // u8 dead-man state.
  const HeadCommand sent{0x0102030405060708ull,
                         {0.5f, -0.25f, 1.0f},
                         0x0A0B0C0Du,
                         0x00012345u,
                         DeadmanState::Released};
  const auto bytes = encode({}, sent);
  ASSERT_EQ(bytes.size(), kHeaderSize + 29);
  EXPECT_EQ(bytes[kHeaderSize], 0x08);
  EXPECT_EQ(bytes[kHeaderSize + 7], 0x01);
  float yaw = 0.0f;
  std::memcpy(&yaw, bytes.data() + kHeaderSize + 8, 4);
  EXPECT_EQ(yaw, 0.5f);
  // The example of PROTOCOL.md 2.3, byte by byte.
  EXPECT_EQ(std::vector<std::uint8_t>(bytes.begin() + kHeaderSize, bytes.end()),
            (std::vector<std::uint8_t>{8,    7,    6,    5,    4,    3,    2,    1,    0,    0,
                                       0,    0x3F, 0,    0,    0x80, 0xBE, 0,    0,    0x80, 0x3F,
                                       0x0D, 0x0C, 0x0B, 0x0A, 0x45, 0x23, 0x01, 0x00, 2}));
  const Result ok = decode(bytes);
  ASSERT_TRUE(ok.ok());
  EXPECT_EQ(std::get<HeadCommand>(ok.envelope->message), sent);
  // The dead-man byte takes 0 (not used), 1 (pressed) and 2 (released) only.
  for (const std::uint8_t state : {0, 1, 2, 3, 0x80, 0xFF}) {
    auto b = bytes;
    b[kHeaderSize + 28] = state;
    reseal(b);
    const Result r = decode(b);
    if (state <= 2) {
      ASSERT_TRUE(r.ok()) << int{state};
      EXPECT_EQ(static_cast<int>(std::get<HeadCommand>(r.envelope->message).deadman), state);
    } else {
      EXPECT_EQ(r.error, ErrorReason::BadPayload) << int{state};
    }
  }
  EXPECT_THROW(encode({}, HeadCommand{0, {}, 0, 0, static_cast<DeadmanState>(3)}),
               std::invalid_argument);
  // A version-3 command (20 bytes, no sample or dead-man) is short, not a command.
  {
    auto b = bytes;
    b.resize(kHeaderSize + 20);
    put_u32(b, 28, 20);
    reseal(b);
    EXPECT_EQ(decode(b).error, ErrorReason::Truncated);
  }
  // A NaN or an angle beyond pi on the wire is a bad payload, not a command.
  for (const float bad : {std::numeric_limits<float>::quiet_NaN(), 3.5f, -4.0f,
                          std::numeric_limits<float>::infinity()}) {
    auto b = bytes;
    std::memcpy(b.data() + kHeaderSize + 12, &bad, 4);
    reseal(b);
    const Result r = decode(b);
    EXPECT_FALSE(r.ok()) << bad;
    EXPECT_EQ(r.error, ErrorReason::BadPayload) << bad;
  }
  EXPECT_THROW(encode({}, HeadCommand{0, {0.0f, 4.0f, 0.0f}, 1, 0, DeadmanState::NotUsed}),
               std::invalid_argument);
  // The manifest's head: a flag byte and three angles after the tile list; angles without the
  // flag are refused (a sender bug shows instead of being read as a pose).
  auto m = encode({}, FrameManifest{7, 64, true, {}, {true, {0.1f, 0.2f, -0.3f}}});
  ASSERT_EQ(m.size(), kHeaderSize + 9 + 13);
  EXPECT_EQ(m[kHeaderSize + 9], 1);
  const Result rm = decode(m);
  ASSERT_TRUE(rm.ok());
  EXPECT_EQ(std::get<FrameManifest>(rm.envelope->message).head.joint_rad[2], -0.3f);
  m[kHeaderSize + 9] = 0;
  reseal(m);
  EXPECT_EQ(decode(m).error, ErrorReason::BadPayload);
  m[kHeaderSize + 9] = 2;
  reseal(m);
  EXPECT_EQ(decode(m).error, ErrorReason::BadPayload);
  // Without the flag every angle byte is zero: -0.0 equals 0 but re-encodes as +0.0 (datagram_fuzz
  // found a manifest that decoded and did not re-encode to its own bytes).
  auto z = encode({}, FrameManifest{7, 64, true, {}, {}});
  ASSERT_TRUE(decode(z).ok());
  z[kHeaderSize + 9 + 1 + 3] = 0x80;  // the yaw angle's sign bit: -0.0f
  reseal(z);
  EXPECT_EQ(decode(z).error, ErrorReason::BadPayload);
  m.resize(m.size() - 1);
  put_u32(m, 28, static_cast<std::uint32_t>(m.size() - kHeaderSize));
  reseal(m);
  EXPECT_EQ(decode(m).error, ErrorReason::Truncated);
}

}  // namespace
}  // namespace telex::proto
