// SPDX-License-Identifier: MIT
// The warp's ground-truth check (`telex warp --check`): a synthetic room of analytic planes and
// boxes with coloured discs on them, the operator's head yawing at a steady rate and the robot head
// following it late; each eye's capture (colour and exact depth) is ray-cast at the robot head's
// pose, shown with and without the warp at the operator's pose, and the discs found in what is
// shown are compared with where the world puts them at that pose.
#pragma once

#include "telex/local/view/warp.h"

namespace telex::local {

struct WarpCheckOptions {
  int width = 1280, height = 720;  // each eye; 90 degrees across
  double yaw_deg_s = 60.0;         // the operator's head
  double lag_ms = 80.0;            // the robot head: the operator's yaw this long ago
  // The depth drawn with each eye pair was captured this long before the pair (the head turned
  // in between): 0 is one instant for both. Then the video is warped from its own pose with the
  // depth brought into it, and also, for comparison, as if captured at the depth's pose.
  double pair_gap_ms = 0.0;
  int frames = 12;  // displayed frames per eye, at frame_rate_hz
  double frame_rate_hz = 30.0;
  WarpOptions warp;
};

struct WarpCheckResult {
  // Mean angle between each visible disc's centre as shown and as the world puts it at the
  // display pose, over both eyes and every frame.
  double error_deg_with = 0.0, error_deg_without = 0.0;
  double max_error_deg_with = 0.0;
  // With pair_gap_ms: the mean error when the video is warped as if captured at the depth's pose
  // (what a pair without its own head pose gets); equal to error_deg_with without a gap.
  double error_deg_depth_pose = 0.0;
  int points_measured = 0;     // disc sightings in both (with and without) of the means
  int points_missed = 0;       // discs in view at both poses but not found in one of them
  double warp_ms_per_eye = 0;  // median of the warps (upload, draw, read back), first frame out
};

// Throws what DepthWarp throws (no EGL) and std::invalid_argument for options out of range.
WarpCheckResult run_warp_check(const WarpCheckOptions& options);

}  // namespace telex::local
