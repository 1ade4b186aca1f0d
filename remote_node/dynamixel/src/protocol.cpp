// SPDX-License-Identifier: MIT
// DYNAMIXEL Protocol 2.0: CRC-16, byte stuffing, packet encoding and the incremental parser.
#include "telex/dynamixel/protocol.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <numbers>

#include "telex/base/demand.h"

namespace telex::dynamixel {

namespace {

// The table of CRC-16 with polynomial 0x8005, most significant bit first (the DynamixelSDK lists
// the same 256 values; tests/remote/dynamixel_protocol_test.cpp compares a few of them).
constexpr std::array<std::uint16_t, 256> make_crc_table() {
  std::array<std::uint16_t, 256> t{};
  for (std::uint32_t i = 0; i < 256; ++i) {
    std::uint32_t crc = i << 8;
    for (int bit = 0; bit < 8; ++bit)
      crc = (crc & 0x8000U) != 0 ? ((crc << 1) ^ 0x8005U) : (crc << 1);
    t[i] = static_cast<std::uint16_t>(crc & 0xFFFFU);
  }
  return t;
}
constexpr std::array<std::uint16_t, 256> kCrcTable = make_crc_table();

constexpr std::uint8_t kHeader[4] = {0xFF, 0xFF, 0xFD, 0x00};

bool is_pattern(std::span<const std::uint8_t> b, std::size_t last) {
  return last >= 2 && b[last - 2] == 0xFF && b[last - 1] == 0xFF && b[last] == 0xFD;
}

std::uint8_t lo(std::uint16_t v) { return static_cast<std::uint8_t>(v & 0xFF); }
std::uint8_t hi(std::uint16_t v) { return static_cast<std::uint8_t>(v >> 8); }

}  // namespace

std::string describe_error(std::uint8_t error_byte) {
  static constexpr const char* kNames[] = {
      "no error",         "result fail",       "instruction error", "CRC error",
      "data range error", "data length error", "data limit error",  "access error",
  };
  const std::uint8_t number = error_byte & kErrorNumberMask;
  std::string s = number < std::size(kNames) ? kNames[number]
                                             : "unknown error number " + std::to_string(number);
  if ((error_byte & kErrorAlert) != 0)
    s += ", hardware alert (the servo's Hardware Error Status, address 70, says which: overload, "
         "overheating, input voltage, encoder or electrical shock)";
  return s;
}

namespace xseries {

std::int32_t counts_from_rad(double angle_rad) {
  return kCentreCounts + static_cast<std::int32_t>(
                             std::lround(angle_rad * kCountsPerTurn / (2.0 * std::numbers::pi)));
}

double rad_from_counts(std::int32_t counts) {
  return static_cast<double>(counts - kCentreCounts) * 2.0 * std::numbers::pi / kCountsPerTurn;
}

std::uint32_t profile_velocity_from_rad_s(double rate_rad_s) {
  const double rpm = rate_rad_s * 60.0 / (2.0 * std::numbers::pi);
  const double units = std::round(rpm / kProfileVelocityRpmPerUnit);
  // 32767 is the register's maximum; the servo caps it further at its Velocity Limit.
  return static_cast<std::uint32_t>(std::clamp(units, 1.0, 32767.0));
}

std::uint32_t profile_acceleration_from_rad_s2(double accel_rad_s2) {
  const double rev_per_min2 = accel_rad_s2 * 3600.0 / (2.0 * std::numbers::pi);
  const double units = std::floor(rev_per_min2 / kProfileAccelerationRpmPerMinPerUnit);
  // 32767 is the register's maximum in the velocity-based profile.
  return static_cast<std::uint32_t>(std::clamp(units, 1.0, 32767.0));
}

std::uint32_t position_limit_counts(double angle_rad) {
  return static_cast<std::uint32_t>(std::clamp(counts_from_rad(angle_rad), 0, kCountsPerTurn - 1));
}

}  // namespace xseries

std::uint16_t crc16(std::span<const std::uint8_t> bytes, std::uint16_t crc) {
  for (const std::uint8_t b : bytes) {
    const auto i = static_cast<std::uint8_t>((crc >> 8) ^ b);
    crc = static_cast<std::uint16_t>((crc << 8) ^ kCrcTable[i]);
  }
  return crc;
}

std::vector<std::uint8_t> add_stuffing(std::span<const std::uint8_t> body) {
  std::vector<std::uint8_t> out;
  out.reserve(body.size() + body.size() / 3 + 1);
  for (std::size_t i = 0; i < body.size(); ++i) {
    out.push_back(body[i]);
    if (is_pattern(body, i)) out.push_back(0xFD);
  }
  return out;
}

std::vector<std::uint8_t> remove_stuffing(std::span<const std::uint8_t> body) {
  std::vector<std::uint8_t> out;
  out.reserve(body.size());
  for (std::size_t i = 0; i < body.size(); ++i) {
    out.push_back(body[i]);
    // The skipped FD is never an FF, so it cannot start or extend a later pattern.
    if (is_pattern(body, i) && i + 1 < body.size() && body[i + 1] == 0xFD) ++i;
  }
  return out;
}

std::vector<std::uint8_t> encode_packet(std::uint8_t id, std::uint8_t instruction,
                                        std::span<const std::uint8_t> params) {
  std::vector<std::uint8_t> body;
  body.reserve(params.size() + 1);
  body.push_back(instruction);
  body.insert(body.end(), params.begin(), params.end());
  const std::vector<std::uint8_t> stuffed = add_stuffing(body);
  const std::size_t length = stuffed.size() + 2;  // + CRC
  TELEX_DEMAND(length <= kMaxLength);
  std::vector<std::uint8_t> out(std::begin(kHeader), std::end(kHeader));
  out.reserve(kHeaderBytes + length);
  out.push_back(id);
  out.push_back(lo(static_cast<std::uint16_t>(length)));
  out.push_back(hi(static_cast<std::uint16_t>(length)));
  out.insert(out.end(), stuffed.begin(), stuffed.end());
  const std::uint16_t crc = crc16(out);
  out.push_back(lo(crc));
  out.push_back(hi(crc));
  return out;
}

std::vector<std::uint8_t> ping_packet(std::uint8_t id) {
  return encode_packet(id, static_cast<std::uint8_t>(Instruction::Ping), {});
}

std::vector<std::uint8_t> read_packet(std::uint8_t id, std::uint16_t address,
                                      std::uint16_t length) {
  const std::uint8_t p[] = {lo(address), hi(address), lo(length), hi(length)};
  return encode_packet(id, static_cast<std::uint8_t>(Instruction::Read), p);
}

std::vector<std::uint8_t> write_packet(std::uint8_t id, std::uint16_t address,
                                       std::span<const std::uint8_t> data) {
  std::vector<std::uint8_t> p{lo(address), hi(address)};
  p.insert(p.end(), data.begin(), data.end());
  return encode_packet(id, static_cast<std::uint8_t>(Instruction::Write), p);
}

std::vector<std::uint8_t> sync_read_packet(std::uint16_t address, std::uint16_t length,
                                           std::span<const std::uint8_t> ids) {
  std::vector<std::uint8_t> p{lo(address), hi(address), lo(length), hi(length)};
  p.insert(p.end(), ids.begin(), ids.end());
  return encode_packet(kBroadcastId, static_cast<std::uint8_t>(Instruction::SyncRead), p);
}

std::vector<std::uint8_t> sync_write_packet(std::uint16_t address, std::uint16_t length,
                                            std::span<const std::uint8_t> ids,
                                            std::span<const std::uint8_t> data) {
  TELEX_DEMAND(data.size() == ids.size() * length);
  std::vector<std::uint8_t> p{lo(address), hi(address), lo(length), hi(length)};
  p.reserve(p.size() + ids.size() * (1 + length));
  for (std::size_t i = 0; i < ids.size(); ++i) {
    p.push_back(ids[i]);
    const auto run = data.subspan(i * length, length);
    p.insert(p.end(), run.begin(), run.end());
  }
  return encode_packet(kBroadcastId, static_cast<std::uint8_t>(Instruction::SyncWrite), p);
}

std::vector<std::uint8_t> status_packet(std::uint8_t id, std::uint8_t error,
                                        std::span<const std::uint8_t> data) {
  std::vector<std::uint8_t> p{error};
  p.insert(p.end(), data.begin(), data.end());
  return encode_packet(id, static_cast<std::uint8_t>(Instruction::Status), p);
}

std::vector<std::uint8_t> le_bytes(std::uint32_t value, std::size_t n) {
  TELEX_DEMAND(n <= 4);
  std::vector<std::uint8_t> out(n);
  for (std::size_t i = 0; i < n; ++i) out[i] = static_cast<std::uint8_t>(value >> (8 * i));
  return out;
}

std::uint32_t le_value(std::span<const std::uint8_t> bytes) {
  TELEX_DEMAND(bytes.size() <= 4);
  std::uint32_t v = 0;
  for (std::size_t i = 0; i < bytes.size(); ++i)
    v |= static_cast<std::uint32_t>(bytes[i]) << (8 * i);
  return v;
}

const char* parse_error_name(ParseError e) {
  switch (e) {
    case ParseError::None:
      return "none";
    case ParseError::BadHeader:
      return "bad header";
    case ParseError::Crc:
      return "CRC mismatch";
  }
  return "?";
}

PacketParser::PacketParser(PacketKind kind, std::size_t max_length)
    : kind_(kind), max_length_(max_length) {
  TELEX_DEMAND(max_length >= 4 && max_length <= 0xFFFF);
  buf_.resize(2 * (kHeaderBytes + max_length));
}

std::size_t PacketParser::feed(std::span<const std::uint8_t> bytes) {
  if (bytes.empty()) return 0;
  if (end_ + bytes.size() > buf_.size() && begin_ > 0) {
    std::memmove(buf_.data(), buf_.data() + begin_, end_ - begin_);
    end_ -= begin_;
    begin_ = 0;
  }
  const std::size_t n = std::min(bytes.size(), buf_.size() - end_);
  std::memcpy(buf_.data() + end_, bytes.data(), n);
  end_ += n;
  return n;
}

void PacketParser::reset() { begin_ = end_ = 0; }

void PacketParser::skip(std::size_t n, bool garbage) {
  begin_ += n;
  if (garbage) counters_.garbage_bytes += n;
  if (begin_ == end_) begin_ = end_ = 0;
}

std::optional<ParseResult> PacketParser::next() {
  while (true) {
    const std::uint8_t* p = buf_.data() + begin_;
    const std::size_t size = end_ - begin_;
    // The first byte that starts a header, or could once more bytes arrive.
    std::size_t start = 0;
    for (; start < size; ++start) {
      bool possible = true;
      for (std::size_t k = 0; k < 4 && start + k < size; ++k)
        if (p[start + k] != kHeader[k]) {
          possible = false;
          break;
        }
      if (possible) break;
    }
    if (start > 0) {
      skip(start, /*garbage=*/true);
      continue;
    }
    if (size < kHeaderBytes) return std::nullopt;

    const std::uint8_t id = p[4];
    const std::size_t length = static_cast<std::size_t>(p[5]) | static_cast<std::size_t>(p[6]) << 8;
    const bool id_ok =
        id <= kMaxDeviceId || (kind_ == PacketKind::Instruction && id == kBroadcastId);
    // A status packet holds at least INST, ERROR and the CRC; an instruction INST and the CRC.
    const std::size_t min_length = kind_ == PacketKind::Status ? 4 : 3;
    if (!id_ok || length < min_length || length > max_length_) {
      ++counters_.bad_headers;
      skip(1, /*garbage=*/false);
      return ParseResult{ParseError::BadHeader, {}};
    }
    const std::size_t total = kHeaderBytes + length;
    if (size < total) return std::nullopt;
    const std::uint16_t crc_rx =
        static_cast<std::uint16_t>(p[total - 2] | static_cast<std::uint16_t>(p[total - 1]) << 8);
    if (crc16({p, total - 2}) != crc_rx) {
      ++counters_.crc_errors;
      skip(1, /*garbage=*/false);
      return ParseResult{ParseError::Crc, {}};
    }
    const std::uint8_t instruction = p[kHeaderBytes];
    const bool status = instruction == static_cast<std::uint8_t>(Instruction::Status);
    if (status != (kind_ == PacketKind::Status)) {
      ++counters_.other_kind;
      skip(total, /*garbage=*/false);
      continue;
    }
    const std::vector<std::uint8_t> body = remove_stuffing({p + kHeaderBytes, length - 2});
    ParseResult r;
    r.packet.id = id;
    r.packet.instruction = instruction;
    const std::size_t first_param = status ? 2 : 1;
    if (status) r.packet.error = body[1];
    r.packet.params.assign(body.begin() + static_cast<std::ptrdiff_t>(first_param), body.end());
    skip(total, /*garbage=*/false);
    ++counters_.packets;
    return r;
  }
}

}  // namespace telex::dynamixel
