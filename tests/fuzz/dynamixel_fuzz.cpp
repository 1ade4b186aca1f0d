// SPDX-License-Identifier: MIT
// libFuzzer target: the DYNAMIXEL Protocol 2.0 packet parser (status and instruction kinds) over
// any bytes fed in any chunks; every packet it returns must survive re-encoding.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "telex/dynamixel/protocol.h"

namespace {

using namespace telex::dynamixel;

// The packet encoded again and parsed again gives the same packet.
void check_round_trip(PacketKind kind, const Packet& p) {
  std::vector<std::uint8_t> body{p.instruction};
  if (kind == PacketKind::Status) body.push_back(p.error);
  body.insert(body.end(), p.params.begin(), p.params.end());
  // A sender that did not stuff FF FF FD is parsed leniently; stuffed again it may no longer fit.
  if (add_stuffing(body).size() + 2 > kMaxLength) return;
  const std::vector<std::uint8_t> bytes =
      kind == PacketKind::Status ? status_packet(p.id, p.error, p.params)
                                 : encode_packet(p.id, p.instruction, std::span(body).subspan(1));
  PacketParser again(kind);
  if (again.feed(bytes) != bytes.size()) __builtin_trap();
  const auto r = again.next();
  if (!r || r->error != ParseError::None || r->packet.id != p.id ||
      r->packet.instruction != p.instruction || r->packet.error != p.error ||
      r->packet.params != p.params)
    __builtin_trap();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  // Byte 0: bit 0 the kind, bit 1 a small LEN bound (64) or the full one, bits 2..7 the chunk size.
  const PacketKind kind = (data[0] & 1) != 0 ? PacketKind::Instruction : PacketKind::Status;
  PacketParser parser(kind, (data[0] & 2) != 0 ? 64 : kMaxLength);
  const std::size_t chunk = 1 + (data[0] >> 2);
  std::span<const std::uint8_t> in(data + 1, size - 1);
  int stalled = 0;
  while (!in.empty()) {
    const std::size_t took = parser.feed(in.first(std::min(chunk, in.size())));
    in = in.subspan(took);
    if (parser.buffered() > parser.capacity()) __builtin_trap();
    // A full buffer always lets next() move on, so feed never refuses twice in a row.
    stalled = took == 0 ? stalled + 1 : 0;
    if (stalled > 1) __builtin_trap();
    while (auto r = parser.next()) {
      if (r->error != ParseError::None) continue;
      const bool status = r->packet.instruction == static_cast<std::uint8_t>(Instruction::Status);
      if (status != (kind == PacketKind::Status)) __builtin_trap();
      check_round_trip(kind, r->packet);
    }
  }
  const std::span<const std::uint8_t> raw(data + 1, size - 1);
  const std::vector<std::uint8_t> body(raw.begin(), raw.end());
  if (remove_stuffing(add_stuffing(body)) != body) __builtin_trap();
  return 0;
}
