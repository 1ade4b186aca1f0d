// SPDX-License-Identifier: MIT
// The headset's tracking space in the NatNet frame (`telex calibrate hmd`): a robot-world /
// hand-eye solve (OpenCV's calibrateRobotWorldHandEye) over moments where both the headset's view
// pose (OpenXR STAGE) and the NatNet head body's pose are known. The CSV reader, the solve and
// its residuals; the command does the rig file.
#pragma once

#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include "telex/calib/calibrate.h"
#include "telex/common/registration.h"

namespace telex::calib {

// The columns of a poses CSV, in this order: the time, the headset's view pose in the STAGE space
// (position metres, unit quaternion x, y, z, w as OpenXR's XrPosef) and the NatNet head rigid
// body's pose in the NatNet frame (as NatNet streams it).
inline constexpr const char* kHmdPoseColumns[] = {
    "time_s",          "stage_view_x_m", "stage_view_y_m", "stage_view_z_m",  "stage_view_qx",
    "stage_view_qy",   "stage_view_qz",  "stage_view_qw",  "natnet_head_x_m", "natnet_head_y_m",
    "natnet_head_z_m", "natnet_head_qx", "natnet_head_qy", "natnet_head_qz",  "natnet_head_qw"};

// A poses CSV that cannot be read: the message names the file, the line and the column.
class PoseCsvError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// One moment seen by both trackers.
struct HmdPoseSample {
  int line = 0;  // in the CSV, for messages
  double t_s = 0.0;
  RigidTransform X_StageView;   // the headset's view frame in the OpenXR STAGE space
  RigidTransform X_NatNetBody;  // the NatNet head body in the NatNet frame
};

// Reads a poses CSV: the header kHmdPoseColumns, then one row per moment. Lines that are empty or
// start with '#' are skipped. Quaternions must be unit to 1 % (they are normalised). Throws
// PoseCsvError naming the file, the line and the column.
std::vector<HmdPoseSample> load_hmd_poses_csv(const std::filesystem::path& path);

struct HmdCalibOptions {
  int min_poses = 3;
  // The head must turn about at least two axes: the rotations of every pose relative to the
  // first (those of at least min_turn_deg) have axes whose spread is at least min_axis_spread_deg
  // (2 atan sqrt(l2 / l1) of their scatter matrix's two largest eigenvalues: the angle between
  // the axes when they are two, equally used).
  double min_turn_deg = 10.0;
  double min_axis_spread_deg = 15.0;
  // The fit must explain the poses: RMS residuals at most these (a CSV with swapped columns or
  // unsynchronised clocks fails here instead of writing a wrong rig).
  double max_rms_mm = 10.0;
  double max_rms_deg = 2.0;
};

struct HmdCalibration {
  // p_NatNet = rotation * p_Stage + translation_m: operator.hmd_stage_in_natnet.
  RigidTransform X_NatNetStage;
  // The headset's view frame in the head body's frame (fixed: the body is on the headset).
  RigidTransform X_BodyView;
  // Per pose: the view frame placed through the head body (X_NatNetBody X_BodyView) against it
  // placed through the stage (X_NatNetStage X_StageView): distance and angle.
  std::vector<double> position_mm, rotation_deg;
  double rms_mm = 0.0, rms_deg = 0.0;
  double max_turn_deg = 0.0;     // the largest rotation relative to the first pose
  double axis_spread_deg = 0.0;  // as HmdCalibOptions::min_axis_spread_deg
};

// The spread of the head's rotation axes (see HmdCalibOptions) and the largest turn, degrees.
struct TurnSpread {
  double max_turn_deg = 0.0;
  double axis_spread_deg = 0.0;
  int turns = 0;  // poses turned at least min_turn_deg from the first
};
TurnSpread turn_spread(const std::vector<HmdPoseSample>& poses, double min_turn_deg);

// Fills position_mm, rotation_deg and the RMS of `c` from its two transforms.
void hmd_residuals(const std::vector<HmdPoseSample>& poses, HmdCalibration& c);

// Solves X_NatNetBody_i X_BodyView = X_NatNetStage X_StageView_i with Shah's method (OpenCV's
// CALIB_ROBOT_WORLD_HAND_EYE_SHAH; Li's dual-quaternion method placed the stage 10 mm off where
// Shah's was 1 mm, on the same noisy rows). Throws CalibrationError with
// fewer than min_poses poses, a head turned about one axis only (or not at all), a failed solve
// or residuals over the limits (naming the worst pose's line).
HmdCalibration calibrate_hmd(const std::vector<HmdPoseSample>& poses,
                             const HmdCalibOptions& options = {});

}  // namespace telex::calib
