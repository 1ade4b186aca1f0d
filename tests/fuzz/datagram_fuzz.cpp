// SPDX-License-Identifier: MIT
// libFuzzer target: one datagram through the datagram parser; accepted messages must re-encode
// to the very same bytes. (Sealed datagrams and TLS records: tls_record_fuzz.)
#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <span>

#include "telex/proto/crc32c.h"
#include "telex/proto/parser.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace telex::proto;
  DatagramParser d;
  d.set_frame_size(640, 480);
  const Result r = d.parse({data, size});
  if (r.ok()) {
    const auto again = encode(r.envelope->header, r.envelope->message);
    if (again.size() != size || !std::equal(again.begin(), again.end(), data)) std::abort();
  }
  // Also try the bytes with a valid CRC, so the fuzzer explores payload validation.
  if (size >= kHeaderSize) {
    std::vector<std::uint8_t> sealed(data, data + size);
    std::fill(sealed.begin() + 32, sealed.begin() + 36, 0);
    const std::uint32_t crc = crc32c(sealed);
    for (int i = 0; i < 4; ++i) sealed[32 + i] = static_cast<std::uint8_t>(crc >> (8 * i));
    const Result s = d.parse(sealed);
    if (s.ok()) {
      const auto again = encode(s.envelope->header, s.envelope->message);
      if (again != sealed) std::abort();
    }
  }
  return 0;
}
