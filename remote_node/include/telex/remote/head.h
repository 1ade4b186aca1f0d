// SPDX-License-Identifier: MIT
// The robot head (yaw, pitch, roll) behind one interface: its limits, the controller that clamps,
// rate-limits and holds still when the operator's link is lost, and the drivers chosen by a spec
// (none | sim | dynamixel:DEV | udp:HOST:PORT).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <numbers>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "telex/common/rig.h"

namespace telex::remote {

inline constexpr std::size_t kHeadJoints = 3;
// Joint angles in radians, in the order yaw, pitch, roll; zero is the head looking straight ahead
// (for Dynamixel servos, position 2048).
using HeadAngles = std::array<double, kHeadJoints>;
const char* head_joint_name(std::size_t joint);  // "yaw", "pitch", "roll"

struct HeadJointLimits {
  double min_rad = 0, max_rad = 0, max_rate_rad_s = 0, max_accel_rad_s2 = 0;
};

struct HeadLimits {
  std::array<HeadJointLimits, kHeadJoints> joint{};
  // Throws std::invalid_argument naming the joint and the value: limits must be finite,
  // -pi <= min < max <= pi (one servo turn), 0 < max_rate, 0 < max_accel.
  void validate() const;
};

// The head's limits from the rig's robot_head.joints (telex/common/rig.h): the defaults live
// there, in one place (yaw +-90 deg, pitch +-45 deg, roll +-30 deg, each at most 180 deg/s and
// 1800 deg/s^2).
HeadLimits head_limits_from(const RobotHead& head);
inline const HeadLimits kDefaultHeadLimits = head_limits_from(RobotHead{});

// The head's joint angles at time_ns (the remote's steady clock, steady_now_ns()). valid = false
// when the driver has none (no head, nothing read yet, a failed read).
struct HeadPose {
  HeadAngles joint_rad{};
  std::int64_t time_ns = 0;
  bool valid = false;
};

// What a driver counted since it was made. Errors never throw in the running loop; they are
// counted here, and the newest is described in last_error.
struct HeadStats {
  std::uint64_t commands = 0;         // command() calls that reached the head
  std::uint64_t rejected = 0;         // command() calls with a non-finite angle, not sent
  std::uint64_t reads = 0;            // measured() calls
  std::uint64_t reads_valid = 0;      // ... that returned a valid pose
  std::uint64_t clamped = 0;          // joint targets clamped to the limits
  std::uint64_t timeouts = 0;         // answers that did not come in time (one per servo)
  std::uint64_t crc_errors = 0;       // packets whose CRC did not match
  std::uint64_t bad_packets = 0;      // malformed, unexpected or wrongly sized answers
  std::uint64_t status_errors = 0;    // a servo refused an instruction (the ERROR byte's number)
  std::uint64_t hardware_errors = 0;  // answers with the hardware alert bit set
  std::uint64_t io_errors = 0;        // failed reads and writes on the port or socket
  std::uint64_t stale = 0;            // udp: poses older than the newest one, dropped
  std::string last_error;
};

class HeadDriver {
 public:
  virtual ~HeadDriver() = default;
  // Moves the head toward target_rad, clamped to the driver's limits (HeadController also limits
  // the rate). Never throws; a failed write is counted.
  virtual void command(const HeadAngles& target_rad, std::int64_t now_ns) = 0;
  // The newest measured pose. Never throws; valid = false (and counted) when none could be read.
  // dynamixel reads the servos here: one bus round trip (about 12 ms for three servos at 57600
  // baud, under 1 ms at 1 Mbaud), so call it from the head's own loop, not a latency-critical one.
  virtual HeadPose measured(std::int64_t now_ns) = 0;
  virtual std::string name() const = 0;
  virtual HeadStats stats() const = 0;
};

// A parsed --head spec.
struct HeadSpec {
  enum class Kind { None, Sim, Dynamixel, Udp };
  Kind kind = Kind::None;
  double sim_tau_s = 0.08;                             // sim: the servos' time constant
  std::string device;                                  // dynamixel: the serial port
  std::array<std::uint8_t, kHeadJoints> ids{1, 2, 3};  // dynamixel: yaw, pitch, roll servo ids
  int baud = 57600;                                    // dynamixel: the X series' factory default
  std::string host;                                    // udp
  std::uint16_t port = 0;                              // udp
};

inline constexpr std::string_view kHeadSpecForms =
    "none | sim[,tau_ms=80] | dynamixel:DEV[,ids=1,2,3][,baud=57600] | udp:HOST:PORT";
// Bauds a dynamixel spec accepts (X series rates that Linux termios names).
inline constexpr std::array<int, 7> kDynamixelBauds{9600,    57600,   115200, 1000000,
                                                    2000000, 3000000, 4000000};

// Throws std::invalid_argument naming the spec, the part that is wrong and the valid forms.
HeadSpec parse_head_spec(std::string_view spec);

// Makes the driver of a spec: validates `limits`, opens the device and checks it answers.
// Throws std::invalid_argument on a bad spec or limits, std::runtime_error when a device is
// missing or silent (naming the device, the ids that did not answer and what to try).
std::unique_ptr<HeadDriver> make_head_driver(std::string_view spec,
                                             const HeadLimits& limits = kDefaultHeadLimits);

// Each angle clamped into [min_rad, max_rad] of its joint; returns how many were clamped.
std::size_t clamp_to_limits(HeadAngles& angles_rad, const HeadLimits& limits);

// One servo of the sim head: a first-order lag of time constant tau_s behind `target`, its speed
// capped at max_rate: dx/dt = clamp((target - x) / tau_s, -max_rate, max_rate). The exact solution
// after dt_s with the target held (linear at max_rate while |target - x| > max_rate * tau_s,
// exponential after), so the result does not depend on how time is split into calls.
double sim_joint_advance(double x_rad, double target_rad, double dt_s, double tau_s,
                         double max_rate_rad_s);

struct HeadControllerConfig {
  HeadLimits limits = kDefaultHeadLimits;
  // No operator target for longer than this: the link is lost and the head holds still.
  double link_timeout_s = 0.2;
  // A target whose tracking sample is older than this is stale: the head holds still
  // (docs/PROTOCOL.md 2.6). Its age is the larger of the age the station sent it with and its age
  // at arrival on the operator's clock, plus the time since it arrived.
  double max_sample_age_s = 0.1;
  // One tracking sample may arrive in several targets (the station sends at 200 Hz, a tracker
  // may stream slower), but not for longer than this on the remote's own clock, from the first
  // target that carried it: NatNet streams at 30 Hz or more (Motive's lowest rate), so a sample
  // legitimately repeats for 33 ms at most, and 50 ms leaves the station's 5 ms send period and
  // the network's jitter. Longer, the station is resending a sample that stopped changing, whatever
  // age it claims, and the head holds still.
  double max_sample_repeat_s = 0.05;
  // A measured pose older than this (HeadPose::time_ns against the update's now) is not where
  // the head is now: the head loop reads, then updates, within one 10 ms loop, and a --head udp
  // controller's pose goes invalid only after 0.5 s. Only the pose before the first command is
  // ever held (HeadController), and only a fresh one.
  double max_measured_age_s = 0.05;
  // The lab requires a dead-man (telex-remote --require-deadman): a station without one ("not
  // used") holds the head as a released one does.
  bool require_deadman = false;
  // Throws std::invalid_argument naming the bad value.
  void validate() const;
};

// The operator's dead-man input as the station reports it (HeadCommand.deadman).
enum class Deadman : std::uint8_t {
  NotUsed = 0,   // the station has none (no --deadman): it does not gate the head
  Pressed = 1,   // held down: the head may move
  Released = 2,  // let go (or the device failed): the head holds still
};

// One operator target: the robot head's joints from one tracking sample of the operator's head,
// with what says whether it may move the head.
struct HeadTarget {
  HeadAngles joint_rad{};
  std::uint32_t sample_id = 0;     // the station's count of tracking samples: a repeat is the same
  std::int64_t sample_age_ns = 0;  // the sample's age when the station sent it (>= 0)
  Deadman deadman = Deadman::NotUsed;
  // When the sample was taken on the station's clock (HeadCommand.operator_ns).
  std::int64_t sample_ns = 0;
  // The sample's age when the command arrived, judged on the operator's clock: the arrival on the
  // remote's clock plus the offset of the remote's heartbeat probes, less sample_ns (negative
  // values, the offset's error, count as 0). It catches what the station's own age cannot: a
  // command that waited in a queue after it was built (issue 49). nullopt while no offset is
  // known: such a target may not move the head (HeadHold::Link).
  std::optional<std::int64_t> arrival_age_ns;
};

// Why the head holds still (HeadController::hold_reason).
enum class HeadHold : std::uint8_t {
  None = 0,  // moving toward the operator's target
  Link,      // no target yet, none for link_timeout_s, or none whose age at arrival is known
  Stale,     // the target's tracking sample is older than max_sample_age_s
  Repeat,    // the same tracking sample for longer than max_sample_repeat_s
  Deadman,   // the operator's dead-man input is released
};
inline constexpr std::size_t kHeadHoldCount = 5;
const char* head_hold_name(HeadHold h);  // "none", "link", "stale", "repeat", "deadman"

struct HeadControlStats {
  std::uint64_t targets = 0;           // operator targets taken
  std::uint64_t rejected_targets = 0;  // non-finite targets, dropped
  std::uint64_t clamped = 0;           // joint targets clamped to the limits
  std::uint64_t rate_limited = 0;      // joint commands held back by max_rate
  std::uint64_t accel_limited = 0;     // joint commands held back by max_accel
  std::uint64_t link_losses = 0;       // times the link went silent for link_timeout_s
  std::uint64_t stale_holds = 0;       // times the head held because the sample was too old
  std::uint64_t repeat_holds = 0;      // ... because one sample repeated too long
  std::uint64_t deadman_holds = 0;     // ... because the dead-man input was released
};

// What the remote commands the head, whatever the driver (pure: time is passed in). Each update
// moves the previous command toward a goal, clamped to the joint limits, with each joint's speed at
// most max_rate_rad_s and its speed changing by at most max_accel_rad_s2 * dt (it slows down in
// time to stop at the goal): the goal is the operator's newest target while it may move the head,
// else the hold pose. The head holds when there is no target for more than link_timeout_s (or
// before the first), when the target's tracking sample is too old or has repeated too long, or
// when the dead-man input is released. The hold pose is where the last command comes to rest
// braking at max_accel (v|v| / 2a past it; the last command itself when it was at rest), fixed
// as the hold begins: the head holds where it was last commanded, and the move there obeys the
// same limits as any other, so neither the hold nor the move that resumes after it jumps. (A
// measured pose is no hold pose once the head has been commanded: it may be old, from a
// controller that stopped answering, and the command to it would be a jump.) Before the first
// command the head is held where it is measured now (no older than max_measured_age_s); without
// such a pose there is nothing to command. The first move starts from the newest valid measured
// pose (the head has not been moved since, by us); a head that never reported one is taken to be
// at zero.
class HeadController {
 public:
  explicit HeadController(HeadControllerConfig config = {});  // validates (throws)

  // A target from the operator's head (the station's HeadCommand) that arrived at now_ns.
  void set_target(const HeadTarget& target, std::int64_t now_ns);
  // The command for now_ns given the newest measured pose; nullopt while there is nothing to
  // command (no target yet and no pose known).
  std::optional<HeadAngles> update(const HeadPose& measured, std::int64_t now_ns);

  bool holding() const { return hold_reason_ != HeadHold::None; }
  HeadHold hold_reason() const { return hold_reason_; }
  // Where the head is held while holding (nullopt while moving, or with nothing to command).
  const std::optional<HeadAngles>& hold_pose() const { return hold_; }
  // The newest target's tracking sample: its id and its age at `now_ns` (the larger of the age it
  // was sent with and its age at arrival, plus the time since it arrived); age -1 without a
  // target.
  std::uint32_t sample_id() const { return target_ ? target_->sample_id : 0; }
  std::int64_t sample_age_ns(std::int64_t now_ns) const;
  std::int64_t sample_ns() const { return target_ ? target_->sample_ns : 0; }
  Deadman deadman() const { return target_ ? target_->deadman : Deadman::NotUsed; }
  const HeadControlStats& stats() const { return stats_; }
  const HeadControllerConfig& config() const { return config_; }

 private:
  HeadHold why_hold(std::int64_t now_ns) const;
  void count_hold(HeadHold why);
  std::optional<HeadAngles> hold(std::int64_t now_ns);
  // The command moved toward `goal` from the last one over the time since the last update.
  void advance(const HeadAngles& goal, std::int64_t now_ns);
  HeadAngles step(const HeadAngles& from, const HeadAngles& goal, double dt_s);

  HeadControllerConfig config_;
  HeadControlStats stats_;
  std::optional<HeadTarget> target_;  // clamped to the limits
  std::int64_t target_ns_ = 0;        // when it arrived
  std::int64_t sample_first_ns_ = 0;  // when its sample first arrived (repeats keep it)
  std::optional<HeadAngles> last_command_;
  HeadAngles velocity_rad_s_{};  // of the last command (kept through holds: no jump to rest)
  std::int64_t last_update_ns_ = 0;
  std::optional<HeadPose> last_measured_;  // the newest valid one, with its time
  std::optional<HeadAngles> hold_;         // the pose held, fixed as the hold begins
  HeadHold hold_reason_ = HeadHold::Link;
};

// --head udp: the datagram both ways (docs/PROTOCOL.md, "Head controller datagrams"): 40 bytes,
// little endian: magic "THD1", u32 sequence, i64 time_ns, f64 yaw, pitch, roll in radians.
inline constexpr std::uint32_t kHeadDatagramMagic = 0x31444854;  // bytes 'T' 'H' 'D' '1'
inline constexpr std::size_t kHeadDatagramBytes = 40;
struct HeadDatagram {
  std::uint32_t sequence = 0;
  std::int64_t time_ns = 0;
  HeadAngles joint_rad{};
};
std::vector<std::uint8_t> encode_head_datagram(const HeadDatagram& d);
// nullopt unless exactly 40 bytes with the magic and finite angles.
std::optional<HeadDatagram> decode_head_datagram(std::span<const std::uint8_t> bytes);

}  // namespace telex::remote
