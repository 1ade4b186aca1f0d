// SPDX-License-Identifier: MIT
// libFuzzer target: the encoded stereo pair's header parser (telex/video/frame_header.h). Any
// bytes give a status; a frame that parses re-serializes to the same bytes.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <span>
#include <vector>

#include "telex/video/frame_header.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace telex::video;
  const std::span<const std::uint8_t> bytes(data, size);
  const ParsedFrame parsed = parse_frame(bytes);
  if (parsed.status != HeaderStatus::Ok) {
    if (!parsed.payload.empty()) std::abort();
    return 0;
  }
  if (parsed.payload.size() != parsed.header.payload_bytes ||
      parsed.payload.data() != data + header_bytes(parsed.header))
    std::abort();
  std::vector<std::uint8_t> again;
  serialize_header(parsed.header, again);
  again.insert(again.end(), parsed.payload.begin(), parsed.payload.end());
  if (again.size() != size || !std::equal(again.begin(), again.end(), data)) std::abort();
  return 0;
}
