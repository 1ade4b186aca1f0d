// SPDX-License-Identifier: MIT
// The operator's head to the remote: HeadCommands with the sample's id, its age, the dead-man.
#include "head_sender.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>

#include "telex/common/head_kinematics.h"

namespace telex::local {

HeadSender::HeadSender(const StationConfig& cfg)
    : cfg_(cfg),
      deadman_(cfg.deadman_spec.empty() || !cfg.head_teleop
                   ? nullptr
                   : open_deadman(parse_deadman_spec(cfg.deadman_spec))) {
  if (deadman_)
    spdlog::info("dead-man {}: the robot head moves only while it is held", deadman_->name());
}

void HeadSender::send(std::int64_t now_ns, TripleBuffer<HeadSample>& head_in,
                      SurfaceClient& client) {
  if (!cfg_.head_teleop || now_ns < next_ns_) return;
  next_ns_ = now_ns + static_cast<std::int64_t>(1e9 / cfg_.head_rate_hz);
  head_in.take(sample_);
  if (sample_.time_ns == 0) return;  // no head tracked yet
  const auto q = head_joints(cfg_.robot_head, sample_.R_BaseCamera);
  // Never a non-finite target (the tracker's poses are checked; this is the last line): the
  // command is not built, and the remote holds the head as it does for a silent station.
  if (!std::all_of(q.begin(), q.end(),
                   [](double v) { return std::isfinite(static_cast<float>(v)); })) {
    ++commands_invalid_;
    return;
  }
  proto::HeadCommand c;
  c.operator_ns = static_cast<std::uint64_t>(sample_.time_ns);
  for (std::size_t j = 0; j < 3; ++j) c.joint_rad[j] = static_cast<float>(q[j]);
  // The sample as it is: when tracking stops, the same id with a growing age, never restamped.
  c.sample_id = sample_.id;
  const std::int64_t age_us = std::max<std::int64_t>(0, now_ns - sample_.time_ns) / 1000;
  c.sample_age_us = static_cast<std::uint32_t>(std::min<std::int64_t>(age_us, 0xFFFFFFFF));
  c.deadman = deadman_ ? deadman_->poll() : proto::DeadmanState::NotUsed;
  client.send_head(c);
  ++commands_;
  if (age_us > 100'000) ++samples_stale_;
  if (c.deadman == proto::DeadmanState::Released) ++deadman_released_;
}

void HeadSender::summarize(StationSummary& s) const {
  s.head_commands = commands_;
  s.head_samples_stale = samples_stale_;
  s.head_deadman_released = deadman_released_;
  s.head_commands_invalid = commands_invalid_;
}

}  // namespace telex::local
