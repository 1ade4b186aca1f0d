// SPDX-License-Identifier: MIT
// --record-hmd-poses: the headset's view in its STAGE space and the NatNet head rigid body at the
// same moments, for `telex calibrate hmd` (docs/RIG.md section 3). The headset is located at each
// frame's predicted display time; NatNet's head body is interpolated to that time between the two
// frames around it. Pure: the station feeds it on its main thread and writes the rows.
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>

#include "telex/common/body_dims.h"

namespace telex::local {

struct HmdPoseRow {
  std::int64_t t_ns = 0;  // the moment (the headset's display time, CLOCK_MONOTONIC)
  Pose X_StageView;       // the headset's VIEW in STAGE (OpenXR's axes)
  Pose X_NatNetHead;      // the head rigid body in the NatNet frame, interpolated to t_ns
};

struct HmdPosePairerStats {
  std::uint64_t rows = 0;           // paired and handed out
  std::uint64_t hmd_taken = 0;      // headset poses taken (one per period)
  std::uint64_t unpaired = 0;       // taken, but no NatNet frame within max_gap_ns on a side
  std::uint64_t natnet_frames = 0;  // head body poses given
};

class HmdPosePairer {
 public:
  struct Config {
    std::int64_t period_ns = 100'000'000;  // a row per 100 ms of the headset's time (10 Hz)
    // Each of the two NatNet frames a row is interpolated between is at most this far from the
    // headset's moment (NatNet at 120 Hz: 8.3 ms apart; a dropped frame or two still pairs).
    std::int64_t max_gap_ns = 25'000'000;
  };
  HmdPosePairer() : HmdPosePairer(Config{}) {}
  explicit HmdPosePairer(Config config) : cfg_(config) {}

  // The head body as NatNet saw it at `sampled_ns` (frames in time order; an older one is
  // ignored).
  void add_natnet(std::int64_t sampled_ns, const Pose& X_NatNetHead);
  // The headset's view at display time `t_ns`; once NatNet has given a frame, the first one at or
  // after each period's tick is taken (rows 10 a second on average, whatever the frame rate).
  void add_hmd(std::int64_t t_ns, const Pose& X_StageView);
  // The oldest row whose moment NatNet's frames now enclose; false when none is ready.
  bool pop(HmdPoseRow& row);
  HmdPosePairerStats stats() const { return stats_; }

  // X_a and X_b mixed: the position linearly, the rotation along the shorter arc; f in [0, 1].
  static Pose interpolate(const Pose& X_a, const Pose& X_b, double f);

 private:
  struct Stamped {
    std::int64_t t_ns = 0;
    Pose X;
  };
  const Config cfg_;
  std::deque<Stamped> natnet_;    // the last frames, oldest first
  std::deque<Stamped> hmd_;       // taken, not yet paired, oldest first
  std::int64_t next_due_ns_ = 0;  // the next headset pose taken is the first at or after it
  bool taken_any_ = false;
  HmdPosePairerStats stats_;
};

}  // namespace telex::local
