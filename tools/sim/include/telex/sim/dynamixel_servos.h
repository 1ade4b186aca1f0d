// SPDX-License-Identifier: MIT
// Emulated DYNAMIXEL X-series servos on one bus (what telex-sim-dynamixel runs): they answer
// PING, READ, WRITE, SYNC_READ and SYNC_WRITE per Protocol 2.0 and move toward their goal at
// their profile velocity; a pseudo-terminal puts them where a serial port would be.
#pragma once

#include <array>
#include <cstdint>
#include <mutex>
#include <span>
#include <stop_token>
#include <string>
#include <thread>
#include <vector>

#include "telex/dynamixel/protocol.h"

namespace telex::sim {

struct DynamixelBusCounters {
  std::uint64_t instructions = 0;  // well-formed instruction packets taken
  std::uint64_t answers = 0;       // status packets sent
  std::uint64_t crc_errors = 0;    // instruction packets with a bad CRC (not answered)
  std::uint64_t bad_headers = 0;
  std::uint64_t malformed = 0;      // parameters that do not fit the instruction
  std::uint64_t goals_refused = 0;  // Goal Positions beyond Min/Max Position Limit, not taken
};

// The bus: bytes from the controller in, the servos' answers out (pure apart from the lock that
// lets a test inspect it while a pty thread serves it). Each servo starts at position 2048 (0 rad),
// torque off, profile velocity and acceleration 0 (no limit), position limits 0..4095, model 1030
// (XM430-W210), firmware 38, position mode. As a real X series servo: EEPROM (below address 64,
// the limits and the operating mode among it) is written only with torque off, and a Goal Position
// beyond Min/Max Position Limit is refused (Data Limit Error; counted in goals_refused).
class DynamixelBus {
 public:
  explicit DynamixelBus(std::vector<std::uint8_t> ids);

  // Takes the controller's bytes (any split), returns what the servos send back, in order. Servos
  // move to now_ns first: toward Goal Position while torque is on, in a trapezoid of their Profile
  // Acceleration (214.577 rev/min^2 units; 0 = no ramp) and Profile Velocity (0.229 rev/min
  // units; 0 = at once).
  std::vector<std::uint8_t> handle(std::span<const std::uint8_t> bytes, std::int64_t now_ns);

  // Inspection and faults, by servo id (a missing id is a test's bug: TELEX_DEMAND).
  std::int32_t goal_counts(std::uint8_t id) const;
  std::int32_t present_counts(std::uint8_t id) const;
  bool torque_enabled(std::uint8_t id) const;
  std::uint32_t profile_velocity(std::uint8_t id) const;
  // Any control table item, as the servo holds it (little endian, 1..4 bytes).
  std::uint32_t register_value(std::uint8_t id, std::uint16_t address, std::size_t bytes) const;
  void set_present_counts(std::uint8_t id, std::int32_t counts);
  void set_operating_mode(std::uint8_t id, std::uint8_t mode);
  // A non-zero Hardware Error Status: every answer carries the alert bit and torque goes off.
  void set_hardware_error(std::uint8_t id, std::uint8_t status);
  void set_silent(std::uint8_t id, bool silent);  // answers nothing
  // The next n status packets go out with their CRC's last byte inverted.
  void corrupt_next_answers(int n);
  DynamixelBusCounters counters() const;

 private:
  struct Servo {
    std::uint8_t id = 0;
    std::array<std::uint8_t, dynamixel::xseries::kControlTableBytes> table{};
    double position_counts = dynamixel::xseries::kCentreCounts;
    double velocity_counts_s = 0;
    bool silent = false;
  };
  Servo* find(std::uint8_t id);
  const Servo* find(std::uint8_t id) const;
  void move_to(std::int64_t now_ns);
  void execute(const dynamixel::Packet& p, std::vector<std::uint8_t>& out);
  // ERROR byte of an answer: the error number plus the alert while a hardware error is set.
  std::uint8_t error_byte(const Servo& s, dynamixel::ErrorNumber e) const;
  dynamixel::ErrorNumber write(Servo& s, std::uint16_t address, std::span<const std::uint8_t> data);
  dynamixel::ErrorNumber read(const Servo& s, std::uint16_t address, std::uint16_t length,
                              std::vector<std::uint8_t>& data) const;
  void answer(const Servo& s, dynamixel::ErrorNumber e, std::span<const std::uint8_t> data,
              std::vector<std::uint8_t>& out);

  mutable std::mutex mu_;
  std::vector<Servo> servos_;
  dynamixel::PacketParser parser_{dynamixel::PacketKind::Instruction};
  std::int64_t last_ns_ = 0;
  bool started_ = false;
  int corrupt_ = 0;
  DynamixelBusCounters counters_;
};

// The bus behind a pseudo-terminal: device() is the path a driver opens as its serial port; a
// thread feeds what the driver writes to the bus and writes the answers back.
class DynamixelPtyServer {
 public:
  // Throws std::runtime_error when no pty can be opened.
  explicit DynamixelPtyServer(std::vector<std::uint8_t> ids);
  ~DynamixelPtyServer();
  DynamixelPtyServer(const DynamixelPtyServer&) = delete;
  DynamixelPtyServer& operator=(const DynamixelPtyServer&) = delete;

  const std::string& device() const { return device_; }
  DynamixelBus& bus() { return bus_; }

 private:
  void serve(std::stop_token stop);

  DynamixelBus bus_;
  int master_ = -1;
  int slave_ = -1;  // kept open so the master never sees a hang-up between driver sessions
  std::string device_;
  std::jthread thread_;  // last: stopped and joined before the descriptors close
};

}  // namespace telex::sim
