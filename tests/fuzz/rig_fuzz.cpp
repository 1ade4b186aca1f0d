// SPDX-License-Identifier: MIT
// libFuzzer target: the rig file parser (any text gives a Rig or a RigError, nothing else), and
// what a parsed rig writes reads back.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "telex/common/rig.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  telex::Rig rig;
  try {
    rig = telex::parse_rig(text, "fuzz");
  } catch (const telex::RigError&) {
    return 0;
  }
  // A rig that loaded must survive its own round trip.
  (void)telex::parse_rig(telex::rig_to_json(rig).dump(), "fuzz round trip");
  return 0;
}
