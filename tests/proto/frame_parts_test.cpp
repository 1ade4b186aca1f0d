// SPDX-License-Identifier: MIT
// Frame parts on the wire (PROTOCOL.md 2.4): the ROI-part header flag and the Hello capability are
// plain bits of existing fields, so every message stays byte-compatible and canonical.
#include <gtest/gtest.h>

#include "telex/proto/messages.h"

namespace telex::proto {
namespace {

TEST(FrameParts, RoiPartFlagIsHeaderBitTwoAndRoundTrips) {
  EXPECT_EQ(kFlagRoiPart, 0x0004);
  EXPECT_EQ(kFlagRoiPart & kFlagKeyFrame, 0);
  Header h;
  h.frame_id = 42;
  h.capture_ns = 123456789;
  h.flags = kFlagKeyFrame | kFlagRoiPart;
  const FrameManifest roi{42, 64, false, {9, 10, 17}, {}};
  const auto bytes = encode(h, roi);
  EXPECT_EQ(bytes[6], 0x05);  // flags, low byte: key frame + ROI part
  EXPECT_EQ(bytes[7], 0x00);
  const Result r = decode(bytes);
  ASSERT_TRUE(r.ok()) << error_reason_name(r.error) << " " << r.detail;
  EXPECT_EQ(r.envelope->header.flags, kFlagKeyFrame | kFlagRoiPart);
  EXPECT_EQ(r.envelope->message, Message{roi});
  EXPECT_EQ(encode(r.envelope->header, r.envelope->message), bytes);  // canonical

  // The closing manifest is an ordinary manifest with the same frame id and no flag.
  h.flags = kFlagKeyFrame;
  const auto closing = encode(h, FrameManifest{42, 64, true, {}, {}});
  const Result c = decode(closing);
  ASSERT_TRUE(c.ok());
  EXPECT_EQ(c.envelope->header.frame_id, 42u);
  EXPECT_EQ(c.envelope->header.flags & kFlagRoiPart, 0);
}

TEST(FrameParts, HelloCapabilityBitFiveRoundTrips) {
  EXPECT_EQ(kCapFrameParts, 1u << 5);
  Hello hello;
  hello.capabilities = kCapDepthTcp | kCapRoi | kCapFrameParts;
  hello.codecs = {Codec::Zip};
  const auto bytes = encode(Header{}, hello);
  // Payload offset 1: capabilities u32 little-endian = 0x29.
  EXPECT_EQ(bytes[kHeaderSize + 1], 0x29);
  const Result r = decode(bytes);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(std::get<Hello>(r.envelope->message).capabilities & kCapFrameParts, kCapFrameParts);
}

}  // namespace
}  // namespace telex::proto
