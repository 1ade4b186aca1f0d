// SPDX-License-Identifier: MIT
// The headset's and NatNet's head poses paired by time, for --record-hmd-poses.
#include "telex/local/inputs/hmd_pose_pairer.h"

#include <algorithm>
#include <glm/gtc/quaternion.hpp>

namespace telex::local {
namespace {

// NatNet frames older than the oldest waiting headset pose by this much are no use.
constexpr std::int64_t kKeepBehindNs = 500'000'000;
// A headset pose NatNet has not reached while the headset went on this long (NatNet stopped):
// given up.
constexpr std::int64_t kGiveUpNs = 1'000'000'000;
constexpr std::size_t kMaxNatNet = 1024, kMaxWaiting = 64;

}  // namespace

Pose HmdPosePairer::interpolate(const Pose& X_a, const Pose& X_b, double f) {
  return {X_a.p_m + (X_b.p_m - X_a.p_m) * f, glm::normalize(glm::slerp(X_a.q, X_b.q, f))};
}

void HmdPosePairer::add_natnet(std::int64_t sampled_ns, const Pose& X_NatNetHead) {
  if (!natnet_.empty() && sampled_ns <= natnet_.back().t_ns) return;
  ++stats_.natnet_frames;
  natnet_.push_back({sampled_ns, X_NatNetHead});
  const std::int64_t keep_from =
      (hmd_.empty() ? sampled_ns : std::min(sampled_ns, hmd_.front().t_ns)) - kKeepBehindNs;
  while (natnet_.size() > kMaxNatNet || (natnet_.size() > 2 && natnet_[1].t_ns < keep_from))
    natnet_.pop_front();
}

void HmdPosePairer::add_hmd(std::int64_t t_ns, const Pose& X_StageView) {
  // Before NatNet's first frame (the station starts the headset's session before the haptic
  // loop) there is nothing to pair with: not taken.
  if (natnet_.empty() || (taken_any_ && t_ns < next_due_ns_)) return;
  // Due every period on the first one's grid (the frames' own period does not slow the rate),
  // again from this one after a gap.
  next_due_ns_ = taken_any_ ? next_due_ns_ + cfg_.period_ns : t_ns + cfg_.period_ns;
  if (next_due_ns_ <= t_ns) next_due_ns_ = t_ns + cfg_.period_ns;
  taken_any_ = true;
  ++stats_.hmd_taken;
  hmd_.push_back({t_ns, X_StageView});
  while (hmd_.size() > kMaxWaiting) {
    hmd_.pop_front();
    ++stats_.unpaired;
  }
}

bool HmdPosePairer::pop(HmdPoseRow& row) {
  while (!hmd_.empty()) {
    const Stamped h = hmd_.front();
    // The first NatNet frame at or after the headset's moment.
    const auto after =
        std::lower_bound(natnet_.begin(), natnet_.end(), h.t_ns,
                         [](const Stamped& s, std::int64_t t) { return s.t_ns < t; });
    if (after == natnet_.end()) {
      // NatNet has not got there yet, unless the headset went on for long without it.
      if (hmd_.back().t_ns - h.t_ns < kGiveUpNs) return false;
      hmd_.pop_front();
      ++stats_.unpaired;
      continue;
    }
    hmd_.pop_front();
    if (after->t_ns == h.t_ns) {
      row = {h.t_ns, h.X, after->X};
    } else if (after == natnet_.begin() || after->t_ns - h.t_ns > cfg_.max_gap_ns ||
               h.t_ns - std::prev(after)->t_ns > cfg_.max_gap_ns) {
      ++stats_.unpaired;
      continue;
    } else {
      const Stamped& before = *std::prev(after);
      const double f = static_cast<double>(h.t_ns - before.t_ns) /
                       static_cast<double>(after->t_ns - before.t_ns);
      row = {h.t_ns, h.X, interpolate(before.X, after->X, f)};
    }
    ++stats_.rows;
    return true;
  }
  return false;
}

}  // namespace telex::local
