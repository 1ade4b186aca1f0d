// SPDX-License-Identifier: MIT
// CRC32C (Castagnoli), the integrity check carried by every message header.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

namespace telex::proto {

// CRC32C of `data`, continuing from `crc` (pass 0 to start). Matches RFC 3720 test vectors.
std::uint32_t crc32c(std::span<const std::uint8_t> data, std::uint32_t crc = 0);

}  // namespace telex::proto
