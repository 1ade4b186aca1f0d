// SPDX-License-Identifier: MIT
// CRC32C against the RFC 3720 / iSCSI check values.
#include "telex/proto/crc32c.h"

#include <gtest/gtest.h>

#include <string_view>
#include <vector>

namespace telex::proto {
namespace {

std::span<const std::uint8_t> bytes(std::string_view s) {
  return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}

TEST(Crc32c, KnownVectors) {
  EXPECT_EQ(crc32c(bytes("123456789")), 0xE3069283u);
  std::vector<std::uint8_t> zeros(32, 0), ones(32, 0xFF);
  EXPECT_EQ(crc32c(zeros), 0x8A9136AAu);
  EXPECT_EQ(crc32c(ones), 0x62A8AB43u);
  EXPECT_EQ(crc32c({}), 0u);
}

TEST(Crc32c, IncrementalEqualsOneShot) {
  const std::string_view s = "The quick brown fox jumps over the lazy dog, twice over.";
  for (std::size_t cut = 0; cut <= s.size(); ++cut) {
    const auto a = crc32c(bytes(s.substr(0, cut)));
    EXPECT_EQ(crc32c(bytes(s.substr(cut)), a), crc32c(bytes(s))) << cut;
  }
}

}  // namespace
}  // namespace telex::proto
