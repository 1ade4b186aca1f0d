// SPDX-License-Identifier: MIT
// The proto sources' names for the project's one little-endian byte cursor (telex/base).
#pragma once

#include "telex/base/byte_cursor.h"

namespace telex::proto::detail {

using Writer = ByteWriter;
using Reader = ByteReader;
inline std::uint32_t load_u32(const std::uint8_t* p) { return load_le_u32(p); }

}  // namespace telex::proto::detail
