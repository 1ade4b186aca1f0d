// SPDX-License-Identifier: MIT
// libFuzzer target: one datagram through the datagram parser; accepted messages must re-encode
// to the very same bytes. Then the same bytes with a valid tag through a keyed parser, so the
// fuzzer reaches decoding and the replay window behind the tag check.
#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <span>

#include "telex/proto/auth.h"
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
  // A valid tag over the bytes as they are: decoding and the replay window run behind it, and
  // an accepted message is seen once only.
  if (size >= kHeaderSize) {
    static const AuthKey key(std::vector<std::uint8_t>(32, 0x42));
    std::vector<std::uint8_t> tagged(data, data + size);
    tagged[6] |= static_cast<std::uint8_t>(kFlagAuth);
    append_tag(tagged, key);
    DatagramParser k;
    k.set_frame_size(640, 480);
    k.set_key(key);
    const Result t = k.parse(tagged);
    if (t.ok() && k.parse(tagged).error != ErrorReason::Replayed) std::abort();
    tagged.back() ^= 1;
    if (k.parse(tagged).ok()) std::abort();
  }
  return 0;
}
