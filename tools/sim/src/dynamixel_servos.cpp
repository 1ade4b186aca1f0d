// SPDX-License-Identifier: MIT
// Emulated DYNAMIXEL X-series servos: the control table, the instructions, the motion, the pty.
#include "telex/sim/dynamixel_servos.h"

#include <fcntl.h>
#include <poll.h>
#include <pty.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <stdexcept>

#include "telex/base/demand.h"

namespace telex::sim {

namespace dxl = telex::dynamixel;
namespace xs = telex::dynamixel::xseries;
using dxl::ErrorNumber;

namespace {

// Control table addresses the emulator gives meaning to, beyond protocol.h's.
constexpr std::uint16_t kReturnDelayTime = 9;
constexpr std::uint16_t kReadOnlyStart = 120;  // Realtime Tick and everything after it
constexpr std::uint16_t kModelXm430W210 = 1030;
constexpr std::uint8_t kFirmware = 38;

void put_le(std::span<std::uint8_t> table, std::uint16_t address, std::uint32_t v, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) table[address + i] = static_cast<std::uint8_t>(v >> (8 * i));
}

std::uint32_t get_le(std::span<const std::uint8_t> table, std::uint16_t address, std::size_t n) {
  return dxl::le_value(table.subspan(address, n));
}

std::int64_t steady_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

}  // namespace

DynamixelBus::DynamixelBus(std::vector<std::uint8_t> ids) {
  for (const std::uint8_t id : ids) {
    TELEX_DEMAND(id <= dxl::kMaxDeviceId);
    Servo s;
    s.id = id;
    put_le(s.table, xs::kModelNumber, kModelXm430W210, 2);
    s.table[xs::kFirmwareVersion] = kFirmware;
    s.table[xs::kId] = id;
    s.table[xs::kBaudRate] = 1;  // 57600
    s.table[kReturnDelayTime] = 250;
    s.table[xs::kOperatingMode] = xs::kPositionMode;
    put_le(s.table, xs::kMaxPositionLimit, 4095, 4);
    put_le(s.table, xs::kMinPositionLimit, 0, 4);
    put_le(s.table, xs::kGoalPosition, xs::kCentreCounts, 4);
    put_le(s.table, xs::kPresentPosition, xs::kCentreCounts, 4);
    servos_.push_back(s);
  }
}

DynamixelBus::Servo* DynamixelBus::find(std::uint8_t id) {
  for (Servo& s : servos_)
    if (s.id == id) return &s;
  return nullptr;
}

const DynamixelBus::Servo* DynamixelBus::find(std::uint8_t id) const {
  for (const Servo& s : servos_)
    if (s.id == id) return &s;
  return nullptr;
}

std::vector<std::uint8_t> DynamixelBus::handle(std::span<const std::uint8_t> bytes,
                                               std::int64_t now_ns) {
  std::lock_guard lock(mu_);
  move_to(now_ns);
  std::vector<std::uint8_t> out;
  while (!bytes.empty()) {
    bytes = bytes.subspan(parser_.feed(bytes));
    while (auto r = parser_.next())
      if (r->error == dxl::ParseError::None) execute(r->packet, out);
  }
  return out;
}

void DynamixelBus::move_to(std::int64_t now_ns) {
  if (!started_) {
    started_ = true;
    last_ns_ = now_ns;
  }
  const double dt_s = static_cast<double>(std::max<std::int64_t>(0, now_ns - last_ns_)) * 1e-9;
  last_ns_ = std::max(last_ns_, now_ns);
  for (Servo& s : servos_) {
    if (s.table[xs::kTorqueEnable] == 0) {
      s.velocity_counts_s = 0;
    } else {
      const auto goal =
          static_cast<double>(static_cast<std::int32_t>(get_le(s.table, xs::kGoalPosition, 4)));
      const std::uint32_t pv = get_le(s.table, xs::kProfileVelocity, 4);
      const std::uint32_t pa = get_le(s.table, xs::kProfileAcceleration, 4);
      if (pv == 0) {
        s.position_counts = goal;
        s.velocity_counts_s = 0;
      } else {
        const double v_max = pv * xs::kProfileVelocityRpmPerUnit / 60.0 * xs::kCountsPerTurn;
        // Profile Acceleration 0: no ramp, the profile velocity at once.
        const double a =
            pa == 0 ? 0.0
                    : pa * xs::kProfileAccelerationRpmPerMinPerUnit / 3600.0 * xs::kCountsPerTurn;
        // A trapezoid, in steps of at most 1 ms: speed up at `a` to the profile velocity, brake
        // at `a` to stop at the goal.
        for (double left = dt_s; left > 0;) {
          const double h = std::min(left, 1e-3);
          left -= h;
          const double d = goal - s.position_counts;
          if (a == 0) {
            s.position_counts =
                std::abs(d) <= v_max * h ? goal : s.position_counts + std::copysign(v_max * h, d);
            continue;
          }
          const double want = std::copysign(std::min(v_max, std::sqrt(2.0 * a * std::abs(d))), d);
          s.velocity_counts_s += std::clamp(want - s.velocity_counts_s, -a * h, a * h);
          const double step = s.velocity_counts_s * h;
          if (std::abs(d) <= std::abs(step) && std::abs(s.velocity_counts_s) <= a * h + 1e-9) {
            s.position_counts = goal;
            s.velocity_counts_s = 0;
          } else {
            s.position_counts += step;
          }
        }
      }
    }
    put_le(s.table, xs::kPresentPosition,
           static_cast<std::uint32_t>(static_cast<std::int32_t>(std::lround(s.position_counts))),
           4);
  }
}

std::uint8_t DynamixelBus::error_byte(const Servo& s, ErrorNumber e) const {
  const bool alert = s.table[xs::kHardwareErrorStatus] != 0;
  return static_cast<std::uint8_t>(static_cast<std::uint8_t>(e) | (alert ? dxl::kErrorAlert : 0));
}

void DynamixelBus::answer(const Servo& s, ErrorNumber e, std::span<const std::uint8_t> data,
                          std::vector<std::uint8_t>& out) {
  std::vector<std::uint8_t> packet = dxl::status_packet(s.id, error_byte(s, e), data);
  if (corrupt_ > 0) {
    --corrupt_;
    packet.back() = static_cast<std::uint8_t>(~packet.back());
  }
  out.insert(out.end(), packet.begin(), packet.end());
  ++counters_.answers;
}

ErrorNumber DynamixelBus::read(const Servo& s, std::uint16_t address, std::uint16_t length,
                               std::vector<std::uint8_t>& data) const {
  data.clear();
  if (length == 0 || static_cast<std::size_t>(address) + length > s.table.size())
    return ErrorNumber::Access;
  data.assign(s.table.begin() + address, s.table.begin() + address + length);
  return ErrorNumber::None;
}

ErrorNumber DynamixelBus::write(Servo& s, std::uint16_t address,
                                std::span<const std::uint8_t> data) {
  const std::size_t end = static_cast<std::size_t>(address) + data.size();
  if (data.empty() || end > kReadOnlyStart) return ErrorNumber::Access;
  if (address < xs::kEepromEnd && s.table[xs::kTorqueEnable] != 0) return ErrorNumber::Access;
  // A 4-byte item written in part.
  for (const std::uint16_t item :
       {xs::kMaxPositionLimit, xs::kMinPositionLimit, xs::kProfileAcceleration,
        xs::kProfileVelocity, xs::kGoalPosition})
    if (address < item + 4 && end > item && (address > item || end < item + 4u))
      return ErrorNumber::DataLength;
  if (address <= xs::kGoalPosition && end >= xs::kGoalPosition + 4u) {
    const auto goal =
        static_cast<std::int32_t>(dxl::le_value(data.subspan(xs::kGoalPosition - address, 4)));
    const auto lo = static_cast<std::int32_t>(get_le(s.table, xs::kMinPositionLimit, 4));
    const auto hi = static_cast<std::int32_t>(get_le(s.table, xs::kMaxPositionLimit, 4));
    if (goal < lo || goal > hi) {
      // As an X series servo does: the goal is not taken (an answer says Data Limit Error).
      ++counters_.goals_refused;
      return ErrorNumber::DataLimit;
    }
  }
  if (address <= xs::kTorqueEnable && end > xs::kTorqueEnable &&
      data[xs::kTorqueEnable - address] != 0 && s.table[xs::kHardwareErrorStatus] != 0)
    return ErrorNumber::ResultFail;  // torque stays off until a reboot clears the error
  std::copy(data.begin(), data.end(), s.table.begin() + address);
  return ErrorNumber::None;
}

void DynamixelBus::execute(const dxl::Packet& p, std::vector<std::uint8_t>& out) {
  ++counters_.instructions;
  const bool broadcast = p.id == dxl::kBroadcastId;
  Servo* target = broadcast ? nullptr : find(p.id);
  if (!broadcast && (target == nullptr || target->silent)) return;  // nobody of that id here
  const auto u16 = [&](std::size_t at) {
    return static_cast<std::uint16_t>(p.params[at] | p.params[at + 1] << 8);
  };
  std::vector<std::uint8_t> data;
  switch (static_cast<dxl::Instruction>(p.instruction)) {
    case dxl::Instruction::Ping: {
      for (Servo& s : servos_) {
        if (s.silent || (!broadcast && &s != target)) continue;
        const std::uint8_t info[] = {s.table[xs::kModelNumber], s.table[xs::kModelNumber + 1],
                                     s.table[xs::kFirmwareVersion]};
        answer(s, ErrorNumber::None, info, out);
      }
      return;
    }
    case dxl::Instruction::Read: {
      if (broadcast) return;  // no status packet for a broadcast READ
      if (p.params.size() != 4) {
        ++counters_.malformed;
        answer(*target, ErrorNumber::DataLength, {}, out);
        return;
      }
      const ErrorNumber e = read(*target, u16(0), u16(2), data);
      answer(*target, e, data, out);
      return;
    }
    case dxl::Instruction::Write: {
      if (p.params.size() < 3) {
        ++counters_.malformed;
        if (!broadcast) answer(*target, ErrorNumber::DataLength, {}, out);
        return;
      }
      const auto payload = std::span(p.params).subspan(2);
      if (broadcast) {
        for (Servo& s : servos_)
          if (!s.silent) (void)write(s, u16(0), payload);
        return;
      }
      answer(*target, write(*target, u16(0), payload), {}, out);
      return;
    }
    case dxl::Instruction::SyncRead: {
      if (!broadcast || p.params.size() < 5) {
        ++counters_.malformed;
        return;
      }
      for (std::size_t i = 4; i < p.params.size(); ++i) {
        const Servo* s = find(p.params[i]);
        if (s == nullptr || s->silent) continue;
        const ErrorNumber e = read(*s, u16(0), u16(2), data);
        answer(*s, e, data, out);
      }
      return;
    }
    case dxl::Instruction::SyncWrite: {
      const std::size_t length = p.params.size() >= 4 ? u16(2) : 0;
      if (!broadcast || length == 0 || (p.params.size() - 4) % (1 + length) != 0) {
        ++counters_.malformed;
        return;
      }
      for (std::size_t at = 4; at < p.params.size(); at += 1 + length) {
        Servo* s = find(p.params[at]);
        if (s != nullptr && !s->silent)
          (void)write(*s, u16(0), std::span(p.params).subspan(at + 1, length));
      }
      return;
    }
    default:
      if (!broadcast) answer(*target, ErrorNumber::Instruction, {}, out);
      return;
  }
}

std::int32_t DynamixelBus::goal_counts(std::uint8_t id) const {
  std::lock_guard lock(mu_);
  const Servo* s = find(id);
  TELEX_DEMAND(s != nullptr);
  return static_cast<std::int32_t>(get_le(s->table, xs::kGoalPosition, 4));
}

std::int32_t DynamixelBus::present_counts(std::uint8_t id) const {
  std::lock_guard lock(mu_);
  const Servo* s = find(id);
  TELEX_DEMAND(s != nullptr);
  return static_cast<std::int32_t>(get_le(s->table, xs::kPresentPosition, 4));
}

bool DynamixelBus::torque_enabled(std::uint8_t id) const {
  std::lock_guard lock(mu_);
  const Servo* s = find(id);
  TELEX_DEMAND(s != nullptr);
  return s->table[xs::kTorqueEnable] != 0;
}

std::uint32_t DynamixelBus::profile_velocity(std::uint8_t id) const {
  return register_value(id, xs::kProfileVelocity, 4);
}

std::uint32_t DynamixelBus::register_value(std::uint8_t id, std::uint16_t address,
                                           std::size_t bytes) const {
  std::lock_guard lock(mu_);
  const Servo* s = find(id);
  TELEX_DEMAND(s != nullptr);
  TELEX_DEMAND(bytes >= 1 && bytes <= 4 && address + bytes <= s->table.size());
  return get_le(s->table, address, bytes);
}

void DynamixelBus::set_present_counts(std::uint8_t id, std::int32_t counts) {
  std::lock_guard lock(mu_);
  Servo* s = find(id);
  TELEX_DEMAND(s != nullptr);
  s->position_counts = counts;
  put_le(s->table, xs::kPresentPosition, static_cast<std::uint32_t>(counts), 4);
}

void DynamixelBus::set_operating_mode(std::uint8_t id, std::uint8_t mode) {
  std::lock_guard lock(mu_);
  Servo* s = find(id);
  TELEX_DEMAND(s != nullptr);
  s->table[xs::kOperatingMode] = mode;
}

void DynamixelBus::set_hardware_error(std::uint8_t id, std::uint8_t status) {
  std::lock_guard lock(mu_);
  Servo* s = find(id);
  TELEX_DEMAND(s != nullptr);
  s->table[xs::kHardwareErrorStatus] = status;
  if (status != 0) s->table[xs::kTorqueEnable] = 0;
}

void DynamixelBus::set_silent(std::uint8_t id, bool silent) {
  std::lock_guard lock(mu_);
  Servo* s = find(id);
  TELEX_DEMAND(s != nullptr);
  s->silent = silent;
}

void DynamixelBus::corrupt_next_answers(int n) {
  std::lock_guard lock(mu_);
  corrupt_ = n;
}

DynamixelBusCounters DynamixelBus::counters() const {
  std::lock_guard lock(mu_);
  DynamixelBusCounters c = counters_;
  c.crc_errors = parser_.counters().crc_errors;
  c.bad_headers = parser_.counters().bad_headers;
  return c;
}

DynamixelPtyServer::DynamixelPtyServer(std::vector<std::uint8_t> ids) : bus_(std::move(ids)) {
  char name[256] = {};
  if (::openpty(&master_, &slave_, name, nullptr, nullptr) != 0)
    throw std::runtime_error(std::string("Dynamixel emulator: cannot open a pseudo-terminal: ") +
                             std::strerror(errno));
  device_ = name;
  // Raw from the start: a cooked pty would echo the driver's bytes back to it.
  termios tio{};
  if (::tcgetattr(slave_, &tio) == 0) {
    ::cfmakeraw(&tio);
    ::tcsetattr(slave_, TCSANOW, &tio);
  }
  ::fcntl(master_, F_SETFL, ::fcntl(master_, F_GETFL) | O_NONBLOCK);
  thread_ = std::jthread([this](std::stop_token stop) { serve(stop); });
}

DynamixelPtyServer::~DynamixelPtyServer() {
  thread_.request_stop();
  if (thread_.joinable()) thread_.join();
  ::close(master_);
  ::close(slave_);
}

void DynamixelPtyServer::serve(std::stop_token stop) {
  std::array<std::uint8_t, 512> buf{};
  while (!stop.stop_requested()) {
    pollfd p{master_, POLLIN, 0};
    if (::poll(&p, 1, 20) <= 0 || (p.revents & POLLIN) == 0) continue;
    const ssize_t n = ::read(master_, buf.data(), buf.size());
    if (n <= 0) continue;
    const std::vector<std::uint8_t> out =
        bus_.handle(std::span(buf.data(), static_cast<std::size_t>(n)), steady_ns());
    std::size_t done = 0;
    while (done < out.size() && !stop.stop_requested()) {
      const ssize_t w = ::write(master_, out.data() + done, out.size() - done);
      if (w > 0) {
        done += static_cast<std::size_t>(w);
      } else {
        pollfd q{master_, POLLOUT, 0};
        ::poll(&q, 1, 20);
      }
    }
  }
}

}  // namespace telex::sim
