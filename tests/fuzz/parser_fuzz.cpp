// SPDX-License-Identifier: MIT
// libFuzzer target: the TCP stream parser over arbitrary bytes fed in arbitrary chunks (the
// plaintext TLS hands over; the records themselves: tls_record_fuzz).
#include <cstdint>
#include <cstdlib>
#include <span>

#include "telex/proto/parser.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  using namespace telex::proto;
  DecodeLimits lim;
  lim.max_message_bytes = 4096;  // small bound so the fuzzer reaches it
  lim.max_tile_pixels = 64 * 64;
  StreamParser p(lim);
  if (data[0] & 1) p.set_frame_size(640, 480);
  const std::size_t chunk = 1 + data[0] % 61;
  std::span<const std::uint8_t> in(data + 1, size - 1);
  while (!in.empty()) {
    const std::size_t took = p.feed(in.first(std::min(chunk, in.size())));
    in = in.subspan(took);
    if (p.buffered() > p.capacity()) std::abort();
    while (auto r = p.next()) {
      if (r->ok()) {
        // Decoded messages are canonical: re-encoding gives a message that decodes the same.
        const auto again = encode(r->envelope->header, r->envelope->message);
        const Result back = decode(again, lim);
        if (!back.ok() || !(back.envelope->message == r->envelope->message)) std::abort();
      }
    }
    if (took == 0) break;  // failed: the caller would close
  }
  (void)p.finish();
  return 0;
}
