// SPDX-License-Identifier: MIT
// The operator's calibrations: arm segment lengths from a T-pose seen by the tracking system and
// each glove sensor's flat-hand and fist values. Pure functions over samples, plus the readers of
// the recorded CSVs (`telex calibrate body|glove` does the devices and the rig file).
#pragma once

#include <array>
#include <filesystem>
#include <glm/glm.hpp>
#include <map>
#include <string>
#include <vector>

#include "telex/calib/calibrate.h"
#include "telex/common/rig.h"

namespace telex::calib {

// ---- body --------------------------------------------------------------------------------------

// One tracking frame: the position of every body that was valid in it (world, metres).
struct TrackingFrame {
  double t_s = 0.0;
  std::map<int, glm::dvec3> p_World_m;
};

// Reads a tracking CSV: the station's --log-tracking (time_s,body_id,x_m,y_m,z_m,qx,qy,qz,qw,valid)
// or a NatNet recording (time_s,body_id,x,y,z,qx,qy,qz,qw). Rows with the same time_s form one
// frame; rows with valid = 0 are left out. Throws std::runtime_error naming the file and line.
std::vector<TrackingFrame> load_tracking_csv(const std::filesystem::path& path);

// The rigid bodies of one arm; elbow -1 = no elbow marker.
struct ArmBodies {
  int shoulder = -1;
  int wrist = -1;
  int elbow = -1;
  int other_shoulder = -1;  // the other side's shoulder, -1 = not tracked (for the line check)
};

struct BodyCalibOptions {
  int min_samples = 30;
  // The arm must hold still and straight: the 10th-90th percentile spread of the shoulder-wrist
  // distance at most this.
  double max_spread_m = 0.01;
  // With elbow markers: the median elbow angle at most this far from straight.
  double max_elbow_bend_rad = 15.0 * 3.14159265358979323846 / 180.0;
  // With both shoulders: the median angle between shoulder-to-wrist and the shoulder line
  // (continued outward) at most this (a T-pose: the arm continues the shoulders).
  double max_off_line_rad = 10.0 * 3.14159265358979323846 / 180.0;
};

// Drillis & Contini's segment ratio (BodyDims' defaults): upper arm 0.186 H, forearm 0.146 H.
inline constexpr double kUpperArmFraction = 0.186 / (0.186 + 0.146);

struct ArmCalibration {
  std::string side;
  double upper_arm_m = 0.0, forearm_m = 0.0;
  double reach_m = 0.0;   // median shoulder-to-wrist distance
  double spread_m = 0.0;  // 10th-90th percentile spread of that distance
  int samples = 0;        // frames with every needed body valid
  bool from_elbow = false;
};

// One arm from T-pose frames: with an elbow marker, upper arm = median |shoulder - elbow| and
// forearm = median |elbow - wrist|; without, the median shoulder-to-wrist distance split by
// kUpperArmFraction. Throws CalibrationError naming the side when there are too few samples or
// the arm is not held straight and still.
ArmCalibration calibrate_arm(const std::vector<TrackingFrame>& frames, const ArmBodies& bodies,
                             const std::string& side, const BodyCalibOptions& options = {});

// ---- glove -------------------------------------------------------------------------------------

// Raw sensor rows (parsed units: USB int16 / 4096, serial byte / 255; full scale 1).
struct GloveCapture {
  int sensor_count = 0;
  std::vector<std::array<double, 14>> rows;
};

// Reads a raw-glove CSV: an optional header line, then one row per report: time_s and one value
// per sensor (5 or 14). Throws std::runtime_error naming the file and line.
GloveCapture load_glove_csv(const std::filesystem::path& path);

struct GloveCalibOptions {
  int min_samples = 10;
  double low_percentile = 5.0;    // of the flat phase: min
  double high_percentile = 95.0;  // of the fist phase: max
  double full_scale = 1.0;
  double min_range_fraction = 0.05;  // of full scale
};

// "thumb near knuckle", "index-middle abduction", "little" ...
std::string glove_sensor_name(int sensor_count, int index);
// Whether the system reads this sensor (a 14-sensor glove's abduction sensors 2, 5, 8, 11 are not).
bool glove_sensor_used(int sensor_count, int index);

struct GloveCalibResult {
  GloveRange range;
  std::vector<int> full_range_sensors;  // unused sensors that did not move: written as 0..1
};

// min = low percentile of the flat phase, max = high percentile of the fist phase, per sensor.
// A used sensor whose range is below min_range_fraction of full scale is a CalibrationError naming
// it; an unused one (abduction) keeps the full range 0..1 instead. Throws CalibrationError for
// too few rows or phases of different sensor counts.
GloveCalibResult calibrate_glove(const GloveCapture& flat, const GloveCapture& fist,
                                 const GloveCalibOptions& options = {});

}  // namespace telex::calib
