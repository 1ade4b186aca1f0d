// SPDX-License-Identifier: MIT
// --head dynamixel:DEV: three X-series servos over Protocol 2.0: pinged, checked for position
// mode, given the rig's limits (their own Min/Max Position Limit, Profile Velocity and
// Acceleration) and torqued at start; SYNC_WRITE of goal positions, SYNC_READ of present positions.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "head_impl.h"
#include "telex/dynamixel/protocol.h"
#include "telex/remote/sources.h"

namespace telex::remote {

namespace {

namespace dxl = telex::dynamixel;
namespace xs = telex::dynamixel::xseries;
using namespace std::chrono_literals;

// Attempts per servo at start, so one lost byte does not fail the start-up.
constexpr int kPingTries = 3;

class DynamixelHead final : public HeadDriver {
 public:
  DynamixelHead(const HeadSpec& spec, const HeadLimits& limits)
      : spec_(spec),
        limits_(limits),
        port_(spec.device, spec.baud),
        parser_(dxl::PacketKind::Status),
        who_("--head dynamixel:" + spec.device) {
    ping_all();
    check_operating_modes();
    program_position_limits();
    for (std::size_t j = 0; j < kHeadJoints; ++j) {
      // The servo's own profile keeps it within the rate and acceleration limits even between our
      // commands, and when it brakes to a hold.
      const HeadJointLimits& l = limits_.joint[j];
      const std::uint32_t pa = xs::profile_acceleration_from_rad_s2(l.max_accel_rad_s2);
      write_checked(j, xs::kProfileAcceleration, dxl::le_bytes(pa, 4), "Profile Acceleration");
      const std::uint32_t pv = xs::profile_velocity_from_rad_s(l.max_rate_rad_s);
      write_checked(j, xs::kProfileVelocity, dxl::le_bytes(pv, 4), "Profile Velocity");
    }
    const HeadPose first = measured(steady_now_ns());
    if (!first.valid)
      throw std::runtime_error(who_ +
                               ": the servos answered a ping but not a SYNC_READ of their "
                               "positions: " +
                               stats_.last_error);
    // The goal where the head is, so torque comes on without a jump to a stale goal (within the
    // limits just programmed: a servo refuses a goal beyond them; from outside, it moves in at its
    // profile's speed).
    HeadAngles goal = first.joint_rad;
    clamp_to_limits(goal, limits_);
    send_goal(goal);
    for (std::size_t j = 0; j < kHeadJoints; ++j)
      write_checked(j, xs::kTorqueEnable, {1}, "Torque Enable");
  }

  // Holds the head where it is: the goal becomes the last measured position (torque stays on, so
  // the head does not drop; power the servos off or disable torque in DYNAMIXEL Wizard to free it).
  ~DynamixelHead() override {
    if (last_valid_) send_goal(last_valid_->joint_rad);
  }

  void command(const HeadAngles& target_rad, std::int64_t /*now_ns*/) override {
    if (!detail::admit_target(target_rad, stats_)) return;
    HeadAngles t = target_rad;
    stats_.clamped += clamp_to_limits(t, limits_);
    if (send_goal(t)) ++stats_.commands;
  }

  HeadPose measured(std::int64_t now_ns) override {
    ++stats_.reads;
    const std::vector<std::uint8_t> request =
        dxl::sync_read_packet(xs::kPresentPosition, 4, spec_.ids);
    const auto answers = transact(request, spec_.ids, 4);
    HeadPose pose;
    if (last_valid_) pose.joint_rad = last_valid_->joint_rad;
    // The servos latch their position as the request ends, one transmission time after now_ns.
    pose.time_ns = now_ns + byte_time_ns(request.size());
    bool all = true;
    for (std::size_t j = 0; j < kHeadJoints; ++j) {
      if (!answers[j]) {
        all = false;
        continue;
      }
      const auto counts = static_cast<std::int32_t>(dxl::le_value(answers[j]->params));
      pose.joint_rad[j] = xs::rad_from_counts(counts);
    }
    pose.valid = all;
    if (all) {
      ++stats_.reads_valid;
      last_valid_ = pose;
    }
    return pose;
  }

  std::string name() const override {
    return fmt::format("dynamixel:{} ids {},{},{} at {} baud (models {}, {}, {})", spec_.device,
                       spec_.ids[0], spec_.ids[1], spec_.ids[2], spec_.baud, models_[0], models_[1],
                       models_[2]);
  }
  HeadStats stats() const override { return stats_; }

 private:
  std::string servo(std::size_t j) const {
    return fmt::format("servo id {} ({})", spec_.ids[j], head_joint_name(j));
  }

  std::int64_t byte_time_ns(std::size_t bytes) const {
    return static_cast<std::int64_t>(bytes) * 10 * 1'000'000'000LL / spec_.baud;  // 8N1
  }

  // How long to wait for `answer_bytes` after sending `request_bytes`: their transmission, each
  // servo's return delay (0.5 ms by default), and twice a USB adapter's default 16 ms latency
  // timer plus 2 ms, as the DynamixelSDK allows.
  std::chrono::microseconds timeout(std::size_t request_bytes, std::size_t answer_bytes,
                                    std::size_t servos) const {
    const std::int64_t wire_ns = byte_time_ns(request_bytes + answer_bytes);
    return std::chrono::microseconds(wire_ns / 1000 + 500 * static_cast<std::int64_t>(servos) +
                                     34'000);
  }

  bool send_goal(const HeadAngles& angles_rad) {
    std::vector<std::uint8_t> data;
    for (const double a : angles_rad) {
      // pi rad would be 4096, one past the position mode's range (a limit of +-pi is allowed).
      const auto counts =
          static_cast<std::uint32_t>(std::clamp(xs::counts_from_rad(a), 0, xs::kCountsPerTurn - 1));
      const auto b = dxl::le_bytes(counts, 4);
      data.insert(data.end(), b.begin(), b.end());
    }
    const auto request = dxl::sync_write_packet(xs::kGoalPosition, 4, spec_.ids, data);
    if (!port_.write_all(request, 50ms)) {
      ++stats_.io_errors;
      stats_.last_error = port_.error();
      return false;
    }
    return true;
  }

  // Sends `request` and collects one status packet from each of `ids` until all came or the
  // time is up. An answer is returned only when well formed: `params` bytes of data and no error
  // number; everything else is counted.
  std::vector<std::optional<dxl::Packet>> transact(std::span<const std::uint8_t> request,
                                                   std::span<const std::uint8_t> ids,
                                                   std::size_t params) {
    std::vector<std::optional<dxl::Packet>> got(ids.size());
    port_.discard_input();
    parser_.reset();
    const auto wait = timeout(request.size(), ids.size() * (11 + params), ids.size());
    if (!port_.write_all(request,
                         std::chrono::duration_cast<std::chrono::milliseconds>(wait) + 1ms)) {
      ++stats_.io_errors;
      stats_.last_error = port_.error();
      return got;
    }
    const auto deadline = std::chrono::steady_clock::now() + wait;
    std::size_t missing = ids.size();
    std::array<std::uint8_t, 256> buf{};
    while (missing > 0) {
      const std::ptrdiff_t n = port_.read_some(buf, deadline);
      if (n < 0) {
        ++stats_.io_errors;
        stats_.last_error = port_.error();
        break;
      }
      if (n == 0) break;
      std::span<const std::uint8_t> in(buf.data(), static_cast<std::size_t>(n));
      while (!in.empty()) {
        in = in.subspan(parser_.feed(in));
        while (auto r = parser_.next()) take(*r, ids, params, got, missing);
      }
    }
    for (std::size_t i = 0; i < ids.size(); ++i)
      if (!got[i] && !refused_[i]) {
        ++stats_.timeouts;
        stats_.last_error = fmt::format("servo id {} did not answer within {} ms", ids[i],
                                        std::chrono::duration<double, std::milli>(wait).count());
      }
    refused_.fill(false);
    return got;
  }

  void take(const dxl::ParseResult& r, std::span<const std::uint8_t> ids, std::size_t params,
            std::vector<std::optional<dxl::Packet>>& got, std::size_t& missing) {
    if (r.error == dxl::ParseError::Crc) {
      ++stats_.crc_errors;
      stats_.last_error = "an answer's CRC did not match";
      return;
    }
    if (r.error != dxl::ParseError::None) {
      ++stats_.bad_packets;
      stats_.last_error = std::string("a malformed answer: ") + dxl::parse_error_name(r.error);
      return;
    }
    const dxl::Packet& p = r.packet;
    const auto it = std::find(ids.begin(), ids.end(), p.id);
    const auto i = static_cast<std::size_t>(it - ids.begin());
    if (it == ids.end() || got[i] || refused_[i]) {
      ++stats_.bad_packets;
      stats_.last_error = fmt::format("an unexpected answer from id {}", p.id);
      return;
    }
    if ((p.error & dxl::kErrorAlert) != 0) {
      ++stats_.hardware_errors;
      stats_.last_error = fmt::format("servo id {}: {}", p.id, dxl::describe_error(p.error));
    }
    if ((p.error & dxl::kErrorNumberMask) != 0) {
      ++stats_.status_errors;
      stats_.last_error = fmt::format("servo id {}: {}", p.id, dxl::describe_error(p.error));
      refused_[i] = true;
      --missing;
      last_refusal_ = p.error;
      return;
    }
    if (p.params.size() != params) {
      ++stats_.bad_packets;
      stats_.last_error =
          fmt::format("servo id {} answered {} bytes, not {}", p.id, p.params.size(), params);
      refused_[i] = true;
      --missing;
      return;
    }
    got[i] = p;
    --missing;
  }

  void ping_all() {
    std::vector<std::size_t> silent;
    for (std::size_t j = 0; j < kHeadJoints; ++j) {
      const std::uint8_t id[] = {spec_.ids[j]};
      bool answered = false;
      for (int attempt = 0; attempt < kPingTries && !answered; ++attempt) {
        auto a = transact(dxl::ping_packet(id[0]), id, 3);
        if (a[0]) {
          answered = true;
          models_[j] = static_cast<int>(dxl::le_value(std::span(a[0]->params).first(2)));
        }
      }
      if (!answered) silent.push_back(j);
    }
    if (silent.empty()) return;
    std::string names, answered;
    for (const std::size_t j : silent) names += (names.empty() ? "" : ", ") + servo(j);
    for (std::size_t j = 0; j < kHeadJoints; ++j)
      if (std::find(silent.begin(), silent.end(), j) == silent.end())
        answered += (answered.empty() ? "" : ", ") + std::to_string(spec_.ids[j]);
    const double wait_ms = std::chrono::duration<double, std::milli>(timeout(10, 14, 1)).count();
    throw std::runtime_error(fmt::format(
        "{}: {} did not answer a ping ({} tries of {:.0f} ms at {} baud; {}). Check that the "
        "servos are powered (12 V: USB alone does not power them) and wired to the adapter, that "
        "the ids are right (DYNAMIXEL Wizard 2.0 scans ids and bauds; set them here with "
        "ids=YAW,PITCH,ROLL) and the baud (the X series ships at 57600; baud=1000000 if you set "
        "1 Mbps); a permission error would have said so (dialout group).",
        who_, names, kPingTries, wait_ms, spec_.baud,
        answered.empty() ? std::string("no id answered") : "ids " + answered + " answered"));
  }

  void check_operating_modes() {
    for (std::size_t j = 0; j < kHeadJoints; ++j) {
      const std::uint8_t id[] = {spec_.ids[j]};
      const auto a = transact(dxl::read_packet(id[0], xs::kOperatingMode, 1), id, 1);
      if (!a[0])
        throw std::runtime_error(
            fmt::format("{}: {} answered a ping but not a READ of its "
                        "Operating Mode: {}",
                        who_, servo(j), stats_.last_error));
      const std::uint8_t mode = a[0]->params[0];
      if (mode == xs::kPositionMode) continue;
      const char* why =
          mode == xs::kExtendedPositionMode
              ? "Extended Position (multi-turn), which ignores the Min/Max Position Limits that "
                "keep the head within the rig's joint limits"
          : mode == xs::kCurrentBasedPositionMode
              ? "Current-based Position (multi-turn), which ignores the Min/Max Position Limits "
                "that keep the head within the rig's joint limits"
              : "a mode that ignores Goal Position";
      throw std::runtime_error(
          fmt::format("{}: {} is in Operating Mode {}: {}; set it to 3 (Position Control Mode) "
                      "with DYNAMIXEL Wizard 2.0 (torque off)",
                      who_, servo(j), mode, why));
    }
  }

  // The rig's joint limits into each servo's own Min/Max Position Limit, so the servo refuses a
  // goal beyond them whatever sends it. They are EEPROM, written only with torque off: a servo
  // whose limits already match (a restart) is left as it is, so a head holding with torque on
  // does not drop; one whose limits differ has torque turned off for the writes (it comes back on
  // at the end of the start).
  void program_position_limits() {
    for (std::size_t j = 0; j < kHeadJoints; ++j) {
      const std::uint32_t want_max = xs::position_limit_counts(limits_.joint[j].max_rad);
      const std::uint32_t want_min = xs::position_limit_counts(limits_.joint[j].min_rad);
      const std::uint8_t id[] = {spec_.ids[j]};
      const auto a = transact(dxl::read_packet(id[0], xs::kMaxPositionLimit, 8), id, 8);
      if (!a[0])
        throw std::runtime_error(
            fmt::format("{}: {} answered a ping but not a READ of its Min/Max Position Limit: {}",
                        who_, servo(j), stats_.last_error));
      const auto have = std::span<const std::uint8_t>(a[0]->params);
      if (dxl::le_value(have.first(4)) == want_max && dxl::le_value(have.subspan(4, 4)) == want_min)
        continue;
      write_checked(j, xs::kTorqueEnable, {0}, "Torque Enable (off, to write the limits)");
      write_checked(j, xs::kMaxPositionLimit, dxl::le_bytes(want_max, 4), "Max Position Limit");
      write_checked(j, xs::kMinPositionLimit, dxl::le_bytes(want_min, 4), "Min Position Limit");
    }
  }

  void write_checked(std::size_t j, std::uint16_t address, const std::vector<std::uint8_t>& data,
                     const char* what) {
    const std::uint8_t id[] = {spec_.ids[j]};
    last_refusal_ = 0;
    const auto a = transact(dxl::write_packet(id[0], address, data), id, 0);
    if (a[0]) return;
    if (last_refusal_ != 0)
      throw std::runtime_error(fmt::format(
          "{}: {} refused {} (address {}): {}{}", who_, servo(j), what, address,
          dxl::describe_error(last_refusal_),
          (last_refusal_ & dxl::kErrorAlert) != 0
              ? "; a hardware error keeps torque off until the servo is rebooted (power cycle)"
              : ""));
    throw std::runtime_error(fmt::format("{}: {} did not confirm {} (address {}): {}", who_,
                                         servo(j), what, address, stats_.last_error));
  }

  HeadSpec spec_;
  HeadLimits limits_;
  detail::SerialPort port_;
  dxl::PacketParser parser_;
  std::string who_;
  std::array<int, kHeadJoints> models_{};
  std::array<bool, kHeadJoints> refused_{};  // per transaction: answered with an error number
  std::uint8_t last_refusal_ = 0;
  std::optional<HeadPose> last_valid_;
  HeadStats stats_;
};

}  // namespace

namespace detail {
std::unique_ptr<HeadDriver> make_dynamixel_head(const HeadSpec& spec, const HeadLimits& limits) {
  return std::make_unique<DynamixelHead>(spec, limits);
}
}  // namespace detail

}  // namespace telex::remote
