// SPDX-License-Identifier: MIT
// HeadController: the operator's target clamped, rate-limited, and held still when the link is
// lost.
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

}  // namespace

void HeadControllerConfig::validate() const {
  limits.validate();
  if (!std::isfinite(link_timeout_s) || !(link_timeout_s > 0))
    throw std::invalid_argument("head link timeout " + std::to_string(link_timeout_s) +
                                " s must be above 0");
}

HeadController::HeadController(HeadControllerConfig config) : config_(config) {
  config_.validate();
}

void HeadController::set_target(const HeadAngles& target_rad, std::int64_t now_ns) {
  if (!all_finite(target_rad)) {
    ++stats_.rejected_targets;
    return;
  }
  HeadAngles t = target_rad;
  stats_.clamped += clamp_to_limits(t, config_.limits);
  target_ = t;
  target_ns_ = now_ns;
  ++stats_.targets;
}

std::optional<HeadAngles> HeadController::update(const HeadPose& measured, std::int64_t now_ns) {
  if (measured.valid && all_finite(measured.joint_rad)) last_measured_ = measured.joint_rad;
  const auto timeout_ns = static_cast<std::int64_t>(config_.link_timeout_s * 1e9);
  const bool link = target_.has_value() && now_ns - target_ns_ <= timeout_ns;
  if (!link) {
    if (!holding_) {
      holding_ = true;
      ++stats_.link_losses;
      hold_.reset();
    }
    if (!hold_) {
      // Latched once, so a drifting or noisy reading does not move the head while it holds.
      const std::optional<HeadAngles>& from = last_measured_ ? last_measured_ : last_command_;
      if (!from) return std::nullopt;
      HeadAngles h = *from;
      clamp_to_limits(h, config_.limits);
      hold_ = h;
    }
    last_command_ = hold_;
    last_update_ns_ = now_ns;
    return hold_;
  }
  holding_ = false;
  hold_.reset();
  if (!last_command_) {
    HeadAngles start = last_measured_ ? *last_measured_ : HeadAngles{};
    clamp_to_limits(start, config_.limits);
    last_command_ = start;
    last_update_ns_ = now_ns;
  }
  const double dt_s =
      static_cast<double>(std::max<std::int64_t>(0, now_ns - last_update_ns_)) * 1e-9;
  HeadAngles cmd = *last_command_;
  for (std::size_t j = 0; j < kHeadJoints; ++j) {
    const double step = config_.limits.joint[j].max_rate_rad_s * dt_s;
    const double delta = (*target_)[j] - cmd[j];
    if (std::abs(delta) > step) {
      cmd[j] += std::copysign(step, delta);
      ++stats_.rate_limited;
    } else {
      cmd[j] = (*target_)[j];
    }
  }
  last_command_ = cmd;
  last_update_ns_ = std::max(last_update_ns_, now_ns);
  return cmd;
}

}  // namespace telex::remote
