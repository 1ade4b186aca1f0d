// SPDX-License-Identifier: MIT
// The NatNet client's checks on what it reads, pure: each body's pose (finite, unit quaternion,
// human speed) and each frame's place in the server's stream (no going back, no running ahead of
// the time that passed here).
#include <algorithm>
#include <cmath>

#include "telex/local/inputs/natnet_client.h"

namespace telex::local {

std::string_view to_string(PoseVerdict v) {
  switch (v) {
    case PoseVerdict::Ok:
      return "ok";
    case PoseVerdict::NonFinite:
      return "non-finite or out-of-range position";
    case PoseVerdict::BadQuaternion:
      return "quaternion not of unit length";
    case PoseVerdict::TooFast:
      return "moved faster than a human";
  }
  return "?";
}

PoseVerdict check_pose(const natnet::RigidBody& body, const PoseLimits& limits,
                       const Pose* previous, double dt_s, Pose& out) {
  const glm::dvec3 p{body.p_m.x, body.p_m.y, body.p_m.z};
  for (int i = 0; i < 3; ++i)
    if (!std::isfinite(p[i]) || std::abs(p[i]) > limits.max_abs_coordinate_m)
      return PoseVerdict::NonFinite;
  const glm::dquat q(body.qw, body.qx, body.qy, body.qz);
  // A NaN component makes the norm NaN, which fails this comparison too.
  const double norm = std::sqrt(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z);
  if (!(std::abs(norm - 1.0) <= limits.quaternion_norm_tolerance))
    return PoseVerdict::BadQuaternion;
  if (previous != nullptr) {
    const double moved_m = glm::length(p - previous->p_m);
    if (moved_m > limits.max_speed_m_per_s * std::max(dt_s, 0.0) + limits.jump_slack_m)
      return PoseVerdict::TooFast;
  }
  out.p_m = p;
  out.q = q / norm;
  return PoseVerdict::Ok;
}

std::string_view to_string(FrameVerdict v) {
  switch (v) {
    case FrameVerdict::Ok:
      return "ok";
    case FrameVerdict::NewTimeline:
      return "a new timeline after a silence";
    case FrameVerdict::Backwards:
      return "frame number or stamp went back";
    case FrameVerdict::TooFarAhead:
      return "frame number or stamp ran ahead of the time that passed";
  }
  return "?";
}

FrameVerdict check_frame(const FrameStamp& previous, const FrameStamp& frame,
                         const TimelineLimits& limits) {
  const double arrival_s = static_cast<double>(frame.received_ns - previous.received_ns) * 1e-9;
  if (arrival_s > limits.resync_s) return FrameVerdict::NewTimeline;
  // Modulo 2^32: the counter wraps (after 414 days at 120 Hz) and stays in order across it.
  const auto frames = static_cast<std::int32_t>(frame.frame_number - previous.frame_number);
  const double stamps_s = frame.timestamp_s - previous.timestamp_s;
  if (frames <= 0 || !(stamps_s >= 0.0)) return FrameVerdict::Backwards;
  const double allowed_s = std::max(0.0, arrival_s) + limits.max_ahead_s;
  if (static_cast<double>(frames) > limits.max_rate_hz * allowed_s || stamps_s > allowed_s)
    return FrameVerdict::TooFarAhead;
  return FrameVerdict::Ok;
}

double speed_check_dt_s(const FrameStamp& previous, const FrameStamp& frame,
                        const TimelineLimits& limits) {
  const double arrival_s =
      std::max(0.0, static_cast<double>(frame.received_ns - previous.received_ns) * 1e-9);
  const double stamps_s = frame.timestamp_s - previous.timestamp_s;
  if (!(stamps_s >= 0.0)) return arrival_s;
  return std::min(stamps_s, arrival_s + limits.max_dt_over_arrival_s);
}

}  // namespace telex::local
