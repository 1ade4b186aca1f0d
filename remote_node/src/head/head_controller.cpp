// SPDX-License-Identifier: MIT
// HeadController: the operator's target clamped, rate- and acceleration-limited, and held still
// when the link is lost, the tracking sample is stale or repeats, or the dead-man is released.
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "telex/remote/head.h"

namespace telex::remote {

namespace {

bool all_finite(const HeadAngles& a) {
  return std::all_of(a.begin(), a.end(), [](double v) { return std::isfinite(v); });
}

std::int64_t to_ns(double s) { return static_cast<std::int64_t>(s * 1e9); }

void check_positive(double v, const char* what) {
  if (!std::isfinite(v) || !(v > 0))
    throw std::invalid_argument(std::string(what) + " " + std::to_string(v) + " s must be above 0");
}

}  // namespace

const char* head_hold_name(HeadHold h) {
  static constexpr const char* kNames[kHeadHoldCount] = {"none", "link", "stale", "repeat",
                                                         "deadman"};
  const auto i = static_cast<std::size_t>(h);
  return i < kHeadHoldCount ? kNames[i] : "?";
}

void HeadControllerConfig::validate() const {
  limits.validate();
  check_positive(link_timeout_s, "head link timeout");
  check_positive(max_sample_age_s, "head max sample age");
  check_positive(max_sample_repeat_s, "head max sample repeat");
  check_positive(max_measured_age_s, "head max measured age");
}

HeadController::HeadController(HeadControllerConfig config) : config_(config) {
  config_.validate();
}

void HeadController::set_target(const HeadTarget& target, std::int64_t now_ns) {
  if (!all_finite(target.joint_rad)) {
    ++stats_.rejected_targets;
    return;
  }
  HeadTarget t = target;
  t.sample_age_ns = std::max<std::int64_t>(0, t.sample_age_ns);
  if (t.arrival_age_ns) t.arrival_age_ns = std::max<std::int64_t>(0, *t.arrival_age_ns);
  stats_.clamped += clamp_to_limits(t.joint_rad, config_.limits);
  if (!target_ || target_->sample_id != t.sample_id) sample_first_ns_ = now_ns;
  target_ = t;
  target_ns_ = now_ns;
  ++stats_.targets;
}

std::int64_t HeadController::sample_age_ns(std::int64_t now_ns) const {
  if (!target_) return -1;
  return std::max(target_->sample_age_ns, target_->arrival_age_ns.value_or(0)) +
         std::max<std::int64_t>(0, now_ns - target_ns_);
}

HeadHold HeadController::why_hold(std::int64_t now_ns) const {
  // A target whose age at arrival cannot be judged (no clock offset yet) is no target yet.
  if (!target_ || !target_->arrival_age_ns || now_ns - target_ns_ > to_ns(config_.link_timeout_s))
    return HeadHold::Link;
  if (target_->deadman == Deadman::Released ||
      (config_.require_deadman && target_->deadman != Deadman::Pressed))
    return HeadHold::Deadman;
  if (sample_age_ns(now_ns) > to_ns(config_.max_sample_age_s)) return HeadHold::Stale;
  // Repeats are counted between arrivals: a silent link is the stale and link rules' to catch.
  if (target_ns_ - sample_first_ns_ > to_ns(config_.max_sample_repeat_s)) return HeadHold::Repeat;
  return HeadHold::None;
}

void HeadController::count_hold(HeadHold why) {
  switch (why) {
    case HeadHold::Link:
      ++stats_.link_losses;
      break;
    case HeadHold::Stale:
      ++stats_.stale_holds;
      break;
    case HeadHold::Repeat:
      ++stats_.repeat_holds;
      break;
    case HeadHold::Deadman:
      ++stats_.deadman_holds;
      break;
    case HeadHold::None:
      break;
  }
}

std::optional<HeadAngles> HeadController::hold(std::int64_t now_ns) {
  if (!last_command_) {
    // Never commanded: the head is where it is measured now, if it was measured now. An older
    // pose may be one a silent controller reported before the head was moved by hand or by it.
    if (!last_measured_ ||
        std::abs(now_ns - last_measured_->time_ns) > to_ns(config_.max_measured_age_s))
      return std::nullopt;
    HeadAngles h = last_measured_->joint_rad;
    clamp_to_limits(h, config_.limits);
    last_command_ = h;
    velocity_rad_s_ = {};
    last_update_ns_ = now_ns;
  }
  if (!hold_) {
    // Fixed once, as the hold begins: where the command comes to rest braking at max_accel, the
    // nearest pose to the last command that the command can stop at without a jump.
    HeadAngles h = *last_command_;
    for (std::size_t j = 0; j < kHeadJoints; ++j) {
      const double v = velocity_rad_s_[j];
      h[j] += v * std::abs(v) / (2.0 * config_.limits.joint[j].max_accel_rad_s2);
    }
    clamp_to_limits(h, config_.limits);
    hold_ = h;
  }
  advance(*hold_, now_ns);
  return last_command_;
}

std::optional<HeadAngles> HeadController::update(const HeadPose& measured, std::int64_t now_ns) {
  if (measured.valid && all_finite(measured.joint_rad)) last_measured_ = measured;
  const HeadHold why = why_hold(now_ns);
  if (why != HeadHold::None) {
    if (hold_reason_ == HeadHold::None) hold_.reset();
    // Counted as each reason begins: a link that goes silent is first a stale sample (100 ms),
    // then a lost link (200 ms), and both are counted.
    if (why != hold_reason_) count_hold(why);
    hold_reason_ = why;
    return hold(now_ns);
  }
  hold_reason_ = HeadHold::None;
  hold_.reset();
  if (!last_command_) {
    HeadAngles start = last_measured_ ? last_measured_->joint_rad : HeadAngles{};
    clamp_to_limits(start, config_.limits);
    last_command_ = start;
    velocity_rad_s_ = {};
    last_update_ns_ = now_ns;
  }
  // From the last command at its speed, hold or not: a move that resumes starts where the hold
  // left the command, so it does not jump either.
  advance(target_->joint_rad, now_ns);
  return last_command_;
}

void HeadController::advance(const HeadAngles& goal, std::int64_t now_ns) {
  const double dt_s =
      static_cast<double>(std::max<std::int64_t>(0, now_ns - last_update_ns_)) * 1e-9;
  if (dt_s > 0) last_command_ = step(*last_command_, goal, dt_s);
  last_update_ns_ = std::max(last_update_ns_, now_ns);
}

// One joint's move toward the goal over dt. The speed it may have now is the lesser of max_rate
// and the speed from which it can still stop at the goal: moving at v for this dt and braking
// at max_accel after must fit the distance, v dt + v^2 / 2a <= d. Then braking by max_accel * dt'
// at every later step, whatever its dt', keeps that true, so the joint stops on the goal without
// ever braking harder than max_accel (the head loop's period wanders). The speed changes toward
// that by at most max_accel * dt. Near the goal the steps shrink quadratically; within 1e-9 rad
// the joint lands on it.
HeadAngles HeadController::step(const HeadAngles& from, const HeadAngles& goal, double dt_s) {
  constexpr double kLandRad = 1e-9;
  HeadAngles cmd = from;
  for (std::size_t j = 0; j < kHeadJoints; ++j) {
    const HeadJointLimits& lim = config_.limits.joint[j];
    const double a = lim.max_accel_rad_s2;
    const double dv_max = a * dt_s;
    const double d = goal[j] - from[j];
    double& v = velocity_rad_s_[j];
    if (std::abs(d) <= kLandRad && std::abs(v) <= dv_max) {
      cmd[j] = goal[j];
      v = d / dt_s;
      continue;
    }
    const auto brake = [&](double distance) {
      return std::sqrt(dv_max * dv_max + 2.0 * a * std::max(0.0, distance)) - dv_max;
    };
    const double v_brake = brake(std::abs(d));
    if (v_brake > lim.max_rate_rad_s) ++stats_.rate_limited;
    double v_want = std::copysign(std::min(lim.max_rate_rad_s, v_brake), d);
    // A target that jumps back toward a joint moving fast is overshot and come back to; a joint
    // limit is not: the speed toward the limit ahead stays one the joint can stop from in time.
    if (v_want > 0) v_want = std::min(v_want, brake(lim.max_rad - from[j]));
    if (v_want < 0) v_want = std::max(v_want, -brake(from[j] - lim.min_rad));
    const double dv = std::clamp(v_want - v, -dv_max, dv_max);
    if (dv != v_want - v) ++stats_.accel_limited;
    v += dv;
    cmd[j] = from[j] + v * dt_s;
  }
  // Only rounding can take a command past a joint limit now; the limit wins.
  if (clamp_to_limits(cmd, config_.limits) > 0)
    for (std::size_t j = 0; j < kHeadJoints; ++j) velocity_rad_s_[j] = (cmd[j] - from[j]) / dt_s;
  return cmd;
}

}  // namespace telex::remote
