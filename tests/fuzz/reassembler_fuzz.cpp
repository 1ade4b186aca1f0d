// SPDX-License-Identifier: MIT
// libFuzzer target: a sequence of datagrams (length-prefixed in the input) into the reassembler.
#include <cstdint>
#include <cstdlib>
#include <span>

#include "telex/proto/fragment.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace telex::proto;
  ReassemblerLimits lim;
  lim.max_message_bytes = 8192;
  lim.max_buffered_bytes = 16384;
  lim.max_in_flight = 4;
  lim.timeout_ns = 1000;
  Reassembler r(lim);
  std::uint64_t now = 0;
  std::span<const std::uint8_t> in(data, size);
  while (in.size() >= 3) {
    const std::size_t len = std::min<std::size_t>(in[0] | (in[1] << 8), in.size() - 3);
    now += in[2] * 10;
    const auto msg = r.push(in.subspan(3, len), now);
    if (msg && (msg->empty() || msg->size() > lim.max_message_bytes)) std::abort();
    if (r.in_flight() > lim.max_in_flight || r.buffered_bytes() > lim.max_buffered_bytes)
      std::abort();
    in = in.subspan(3 + len);
  }
  return 0;
}
