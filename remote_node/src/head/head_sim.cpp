// SPDX-License-Identifier: MIT
// --head sim: three servos, each a first-order lag behind its target with a rate limit, advanced
// exactly from one call's time to the next.
#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "head_impl.h"

namespace telex::remote {

double sim_joint_advance(double x_rad, double target_rad, double dt_s, double tau_s,
                         double max_rate_rad_s) {
  if (!(dt_s > 0)) return x_rad;
  double error = target_rad - x_rad;
  // Within this distance of the target the lag is slower than the rate limit.
  const double band = max_rate_rad_s * tau_s;
  if (std::abs(error) > band) {
    const double t_linear_s = (std::abs(error) - band) / max_rate_rad_s;
    if (dt_s <= t_linear_s) return x_rad + std::copysign(max_rate_rad_s * dt_s, error);
    dt_s -= t_linear_s;
    error = std::copysign(band, error);
  }
  return target_rad - error * std::exp(-dt_s / tau_s);
}

namespace {

class SimHead final : public HeadDriver {
 public:
  SimHead(double tau_s, const HeadLimits& limits) : tau_s_(tau_s), limits_(limits) {}

  void command(const HeadAngles& target_rad, std::int64_t now_ns) override {
    if (!detail::admit_target(target_rad, stats_)) return;
    advance(now_ns);
    target_ = target_rad;
    stats_.clamped += clamp_to_limits(target_, limits_);
    ++stats_.commands;
  }

  HeadPose measured(std::int64_t now_ns) override {
    advance(now_ns);
    ++stats_.reads;
    ++stats_.reads_valid;
    return HeadPose{x_rad_, t_ns_, true};
  }

  std::string name() const override { return fmt::format("sim,tau_ms={:g}", tau_s_ * 1000.0); }
  HeadStats stats() const override { return stats_; }

 private:
  // Time only moves forward: an earlier now_ns leaves the state (and its time) as it is.
  void advance(std::int64_t now_ns) {
    if (!started_) {
      started_ = true;
      t_ns_ = now_ns;
      return;
    }
    if (now_ns <= t_ns_) return;
    const double dt_s = static_cast<double>(now_ns - t_ns_) * 1e-9;
    for (std::size_t j = 0; j < kHeadJoints; ++j)
      x_rad_[j] =
          sim_joint_advance(x_rad_[j], target_[j], dt_s, tau_s_, limits_.joint[j].max_rate_rad_s);
    t_ns_ = now_ns;
  }

  double tau_s_;
  HeadLimits limits_;
  HeadAngles x_rad_{};
  HeadAngles target_{};
  std::int64_t t_ns_ = 0;
  bool started_ = false;
  HeadStats stats_;
};

}  // namespace

namespace detail {
std::unique_ptr<HeadDriver> make_sim_head(const HeadSpec& spec, const HeadLimits& limits) {
  return std::make_unique<SimHead>(spec.sim_tau_s, limits);
}
}  // namespace detail

}  // namespace telex::remote
