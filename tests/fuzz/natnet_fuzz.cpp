// SPDX-License-Identifier: MIT
// libFuzzer target: NatNet packet framing, FRAMEOFDATA in every layout, and server info.
#include <cstddef>
#include <cstdint>
#include <span>

#include "telex/natnet/natnet.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace telex::local::natnet;
  if (size < 1) return 0;
  // The first byte picks the layout so one corpus covers 2.0 .. 4.1 (2.3 and 2.6 appended later,
  // so the kept corpus keeps the versions it was found with).
  static constexpr Version kVersions[] = {{2, 0}, {2, 5}, {2, 7}, {2, 9}, {2, 11}, {3, 0},
                                          {3, 1}, {4, 0}, {4, 1}, {2, 3}, {2, 6}};
  const Version v = kVersions[data[0] % std::size(kVersions)];
  const std::span<const std::uint8_t> bytes(data + 1, size - 1);
  static Frame frame;  // reused like the client does, to exercise clear() with capacity
  PacketView pkt;
  if (parse_packet(bytes, pkt).ok()) {
    if (pkt.message_id == kFrameOfData) {
      const ParseStatus st = parse_frame(pkt.payload, v, frame);
      if (!st.ok() && st.offset > pkt.payload.size()) __builtin_trap();
    } else if (pkt.message_id == kPingResponse) {
      ServerInfo info;
      (void)parse_server_info(pkt.payload, info);
    }
  }
  const ParseStatus st = parse_frame(bytes, v, frame);
  if (!st.ok() && st.offset > bytes.size()) __builtin_trap();
  return 0;
}
