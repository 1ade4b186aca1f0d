// SPDX-License-Identifier: MIT
// The byte cursor on known bytes: little-endian whatever the host, bounds checked, sticky failure.
#include "telex/base/byte_cursor.h"

#include <gtest/gtest.h>

#include <limits>

namespace telex {
namespace {

TEST(ByteCursor, WritesLittleEndianBytes) {
  std::vector<std::uint8_t> out;
  ByteWriter w(out);
  w.u16(0x1234);
  w.u32(0xA1B2C3D4u);
  w.put(std::int16_t{-2});
  w.f32(1.0f);  // 0x3F800000
  w.u64(0x0102030405060708ull);
  w.cstring("ab");
  const std::vector<std::uint8_t> want{0x34, 0x12, 0xD4, 0xC3, 0xB2, 0xA1, 0xFE, 0xFF,
                                       0x00, 0x00, 0x80, 0x3F, 0x08, 0x07, 0x06, 0x05,
                                       0x04, 0x03, 0x02, 0x01, 'a',  'b',  0x00};
  EXPECT_EQ(out, want);
  w.patch_u32(2, 7);
  EXPECT_EQ(out[2], 7);
  EXPECT_EQ(out[5], 0);
  EXPECT_THROW(w.patch_u32(out.size() - 2, 1), std::out_of_range);
}

TEST(ByteCursor, ReadsKnownBytesAndRoundTrips) {
  const std::vector<std::uint8_t> in{0x34, 0x12, 0xD4, 0xC3, 0xB2, 0xA1, 0xFE, 0xFF,
                                     0x00, 0x00, 0x80, 0x3F, 'h',  'i',  0x00, 0x09};
  ByteReader r(in);
  EXPECT_EQ(r.u16(), 0x1234);
  EXPECT_EQ(r.u32(), 0xA1B2C3D4u);
  EXPECT_EQ(r.read<std::int16_t>(), -2);
  EXPECT_EQ(r.f32(), 1.0f);
  std::string s;
  EXPECT_TRUE(r.cstring(s));
  EXPECT_EQ(s, "hi");
  EXPECT_EQ(r.offset(), 15u);
  EXPECT_EQ(r.u8(), 9);
  EXPECT_TRUE(r.ok());
  EXPECT_EQ(r.remaining(), 0u);

  std::vector<std::uint8_t> buf;
  ByteWriter w(buf);
  w.f64(-0.1);
  w.put(std::numeric_limits<std::int64_t>::min());
  ByteReader back(buf);
  EXPECT_EQ(back.f64(), -0.1);
  EXPECT_EQ(back.read<std::int64_t>(), std::numeric_limits<std::int64_t>::min());
}

TEST(ByteCursor, AShortReadFailsAndStaysFailed) {
  const std::vector<std::uint8_t> in{1, 2, 3};
  ByteReader r(in);
  std::uint32_t v = 77;
  EXPECT_FALSE(r.get(v));
  EXPECT_EQ(v, 77u);  // untouched
  EXPECT_FALSE(r.ok());
  EXPECT_EQ(r.u8(), 0);  // sticky: even a read that would fit now fails
  EXPECT_TRUE(r.bytes(1).empty());
  ByteReader no_nul(in);
  std::string s;
  EXPECT_FALSE(no_nul.cstring(s));
  EXPECT_FALSE(no_nul.ok());
  ByteReader skipping(in);
  EXPECT_TRUE(skipping.skip(3));
  EXPECT_FALSE(skipping.skip(1));
}

}  // namespace
}  // namespace telex
