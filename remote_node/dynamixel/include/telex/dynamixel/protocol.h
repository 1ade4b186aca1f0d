// SPDX-License-Identifier: MIT
// DYNAMIXEL Protocol 2.0 packets: CRC-16, byte stuffing, instruction and status encoding and an
// incremental packet parser over a byte stream. Pure (bytes in, values out); no port here.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace telex::dynamixel {

// ROBOTIS e-manual, "DYNAMIXEL Protocol 2.0": FF FF FD 00, ID, LEN (little endian: instruction +
// parameters + CRC, after stuffing), INST, parameters, CRC-16 (little endian) over everything
// before it. Status packets are instruction 0x55 with the ERROR byte as their first parameter.
inline constexpr std::uint8_t kMaxDeviceId = 0xFC;  // 0..252 name one device
inline constexpr std::uint8_t kBroadcastId = 0xFE;
inline constexpr std::size_t kHeaderBytes = 7;  // FF FF FD 00 ID LEN_L LEN_H
// The largest LEN this parser accepts (the DynamixelSDK's RXPACKET_MAX_LEN).
inline constexpr std::size_t kMaxLength = 1024;

enum class Instruction : std::uint8_t {
  Ping = 0x01,
  Read = 0x02,
  Write = 0x03,
  Status = 0x55,
  SyncRead = 0x82,
  SyncWrite = 0x83,
};

// The status packet's ERROR byte: bit 7 is the alert (the device's Hardware Error Status is not
// zero), bits 0..6 the error number of the instruction just processed.
inline constexpr std::uint8_t kErrorAlert = 0x80;
inline constexpr std::uint8_t kErrorNumberMask = 0x7F;
enum class ErrorNumber : std::uint8_t {
  None = 0,
  ResultFail = 1,
  Instruction = 2,
  Crc = 3,
  DataRange = 4,
  DataLength = 5,
  DataLimit = 6,
  Access = 7,
};
// "result fail", "instruction error", ... "access error" (and the alert) for messages.
std::string describe_error(std::uint8_t error_byte);

// The X series' control table (XL430, XC430, XM430, XM540, XH430, ...: e-manual control tables).
namespace xseries {
inline constexpr std::uint16_t kModelNumber = 0;            // 2 bytes
inline constexpr std::uint16_t kFirmwareVersion = 6;        // 1 byte
inline constexpr std::uint16_t kId = 7;                     // 1 byte
inline constexpr std::uint16_t kBaudRate = 8;               // 1 byte (1 = 57600)
inline constexpr std::uint16_t kOperatingMode = 11;         // 1 byte
inline constexpr std::uint16_t kMaxPositionLimit = 48;      // 4 bytes, EEPROM (position mode)
inline constexpr std::uint16_t kMinPositionLimit = 52;      // 4 bytes, EEPROM (position mode)
inline constexpr std::uint16_t kEepromEnd = 64;             // EEPROM below: writable torque off
inline constexpr std::uint16_t kTorqueEnable = 64;          // 1 byte; EEPROM locks while 1
inline constexpr std::uint16_t kHardwareErrorStatus = 70;   // 1 byte
inline constexpr std::uint16_t kProfileAcceleration = 108;  // 4 bytes, 0 = no limit
inline constexpr std::uint16_t kProfileVelocity = 112;      // 4 bytes, 0 = no limit
inline constexpr std::uint16_t kGoalPosition = 116;         // 4 bytes
inline constexpr std::uint16_t kPresentPosition = 132;      // 4 bytes, signed
inline constexpr std::uint16_t kControlTableBytes = 147;    // through Present Temperature (146)
// Operating modes that take Goal Position: position, extended position, current-based position.
// Only position mode (3) keeps a goal within Min/Max Position Limit; the other two are multi-turn
// and ignore those limits.
inline constexpr std::uint8_t kPositionMode = 3;
inline constexpr std::uint8_t kExtendedPositionMode = 4;
inline constexpr std::uint8_t kCurrentBasedPositionMode = 5;
inline constexpr std::int32_t kCountsPerTurn = 4096;
inline constexpr std::int32_t kCentreCounts = 2048;  // 0 rad
inline constexpr double kProfileVelocityRpmPerUnit = 0.229;
inline constexpr double kProfileAccelerationRpmPerMinPerUnit = 214.577;  // rev/min^2
// Position counts <-> joint angle (2048 = 0 rad, 4096 counts a turn); counts are rounded.
std::int32_t counts_from_rad(double angle_rad);
double rad_from_counts(std::int32_t counts);
// Profile Velocity units (0.229 rev/min) for a joint rate, at least 1 (0 would mean no limit).
std::uint32_t profile_velocity_from_rad_s(double rate_rad_s);
// Profile Acceleration units (214.577 rev/min^2) for a joint acceleration, rounded down so the
// servo never accelerates harder than asked, at least 1 (0 would mean no limit).
std::uint32_t profile_acceleration_from_rad_s2(double accel_rad_s2);
// A joint limit as a Min/Max Position Limit: the counts of the angle, within 0..4095.
std::uint32_t position_limit_counts(double angle_rad);
}  // namespace xseries

// CRC-16 of Protocol 2.0 (polynomial 0x8005, initial value `crc`, not reflected: the
// DynamixelSDK's updateCRC).
std::uint16_t crc16(std::span<const std::uint8_t> bytes, std::uint16_t crc = 0);

// Byte stuffing of the instruction and parameter bytes: every FF FF FD gets an FD after it, so a
// header never appears inside a packet; remove_stuffing drops the FD after each FF FF FD.
std::vector<std::uint8_t> add_stuffing(std::span<const std::uint8_t> body);
std::vector<std::uint8_t> remove_stuffing(std::span<const std::uint8_t> body);

// One whole packet: header, id, LEN, the stuffed instruction and parameters, CRC. The stuffed
// length must fit kMaxLength (a caller's bug otherwise: TELEX_DEMAND).
std::vector<std::uint8_t> encode_packet(std::uint8_t id, std::uint8_t instruction,
                                        std::span<const std::uint8_t> params);

// Instruction packets.
std::vector<std::uint8_t> ping_packet(std::uint8_t id);
std::vector<std::uint8_t> read_packet(std::uint8_t id, std::uint16_t address, std::uint16_t length);
std::vector<std::uint8_t> write_packet(std::uint8_t id, std::uint16_t address,
                                       std::span<const std::uint8_t> data);
// Broadcast; each device in `ids` answers in turn with `length` bytes from `address`.
std::vector<std::uint8_t> sync_read_packet(std::uint16_t address, std::uint16_t length,
                                           std::span<const std::uint8_t> ids);
// Broadcast, no answer; `data` holds ids.size() runs of `length` bytes, one per id in order.
std::vector<std::uint8_t> sync_write_packet(std::uint16_t address, std::uint16_t length,
                                            std::span<const std::uint8_t> ids,
                                            std::span<const std::uint8_t> data);
// A status packet (what a device answers): ERROR byte, then `data`.
std::vector<std::uint8_t> status_packet(std::uint8_t id, std::uint8_t error,
                                        std::span<const std::uint8_t> data);

// Little-endian helpers for the control table's multi-byte fields.
std::vector<std::uint8_t> le_bytes(std::uint32_t value, std::size_t n);
std::uint32_t le_value(std::span<const std::uint8_t> bytes);  // up to 4 bytes

// A packet as parsed: stuffing removed. For status packets `error` is the ERROR byte and `params`
// what follows it; for instruction packets `error` is 0 and `params` all parameters.
struct Packet {
  std::uint8_t id = 0;
  std::uint8_t instruction = 0;
  std::uint8_t error = 0;
  std::vector<std::uint8_t> params;
};

// Which packets a parser returns: a controller reads status packets (and skips its own
// instructions where a half-duplex adapter echoes them); a device reads instruction packets (and
// skips the other devices' status packets on the shared bus).
enum class PacketKind { Status, Instruction };

enum class ParseError {
  None,
  BadHeader,  // FF FF FD 00 followed by an impossible id or LEN for the kind
  Crc,        // the CRC did not match
};
const char* parse_error_name(ParseError e);

struct ParseResult {
  ParseError error = ParseError::None;
  Packet packet;  // valid when error == None
};

struct ParserCounters {
  std::uint64_t packets = 0;        // returned
  std::uint64_t bad_headers = 0;    // ParseError::BadHeader
  std::uint64_t crc_errors = 0;     // ParseError::Crc
  std::uint64_t other_kind = 0;     // well-formed packets of the other kind, skipped
  std::uint64_t garbage_bytes = 0;  // bytes skipped while looking for a header
};

// Bytes in: feed(); packets out: next(). Never touches a port.
//
// Memory: at most capacity() = 2 * (kHeaderBytes + max_length) bytes are buffered; feed() takes
// only what fits and returns how many bytes it took, so a caller drains with next() and feeds the
// rest (a full buffer always holds a whole packet or a bad header, so next() makes progress).
//
// Resynchronisation (the e-manual's "processing order of reception"): bytes before a header
// FF FF FD 00 are skipped as garbage (FF FF FD FD is stuffed data, not a header). A header whose
// id or LEN is impossible, or a packet whose CRC does not match, is reported once and parsing
// resumes one byte after its first byte, so a real packet that began inside it is still found.
class PacketParser {
 public:
  explicit PacketParser(PacketKind kind, std::size_t max_length = kMaxLength);

  [[nodiscard]] std::size_t feed(std::span<const std::uint8_t> bytes);
  // A packet or an error; nullopt when more bytes are needed.
  std::optional<ParseResult> next();
  // Drops buffered bytes (a controller starting a new transaction).
  void reset();

  std::size_t buffered() const { return end_ - begin_; }
  std::size_t capacity() const { return buf_.size(); }
  const ParserCounters& counters() const { return counters_; }

 private:
  void skip(std::size_t n, bool garbage);

  PacketKind kind_;
  std::size_t max_length_;
  std::vector<std::uint8_t> buf_;
  std::size_t begin_ = 0;
  std::size_t end_ = 0;
  ParserCounters counters_;
};

}  // namespace telex::dynamixel
