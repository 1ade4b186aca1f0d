// SPDX-License-Identifier: MIT
// The rig file (docs/RIG.md): one JSON file that both daemons read with --rig, holding everything
// about a lab's setup that is not a tuning choice: the depth sensor's and the eyes' intrinsics and
// distortion, the extrinsics between them, the robot head's joints, the operator's marker bodies,
// body segments, gloves and haptic display channels. Every key is optional: an absent key keeps
// the built-in default, so a rig file grows as a lab calibrates. Unknown keys, wrong types and
// out-of-range values are errors naming the key's full path.
#pragma once

#include <array>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "telex/common/body_dims.h"
#include "telex/common/depth_image.h"
#include "telex/common/registration.h"

namespace telex {

// A bad rig file: the message starts with "rig FILE: " and names the key ("eyes.left.fx_px").
class RigError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

// A camera with lens distortion (OpenCV's model: k1, k2, p1, p2, k3).
struct CameraModel {
  Intrinsics k;
  std::array<double, 5> distortion{};
};

// One joint of the robot head (yaw, pitch, roll in that order, each turning the ones after it).
struct RobotHeadJoint {
  std::string name;
  glm::dvec3 axis{0.0, 1.0, 0.0};  // unit, in the head base's frame at zero angles
  double min_rad = -1.0, max_rad = 1.0;
  double max_rate_rad_s = 3.14159265358979323846;
  int servo_id = -1;  // Dynamixel id; -1 = none given
  // The controller's (and the servos' Profile Acceleration's) bound on the joint's acceleration.
  double max_accel_rad_s2 = 10.0 * 3.14159265358979323846;
};

// The rig's bounds on a head joint's speed and acceleration (docs/RIG.md): a head turning faster
// than a person's head does is a hazard beside people, whatever its servos could do.
inline constexpr double kMaxHeadRateDegS = 360.0;
inline constexpr double kMaxHeadAccelDegS2 = 7200.0;

struct RobotHead {
  std::array<RobotHeadJoint, 3> joints = default_joints();
  // The right eye camera in the head's last link: p_link = rotation * p_eye + translation_m.
  RigidTransform X_LinkRightEye{};
  static std::array<RobotHeadJoint, 3> default_joints();
};

// Rigid body ids the tracking system streams (-1 = not streamed).
struct MarkerBodies {
  int head = 1;
  int right_hand = 2;
  int right_shoulder = 3;
  int left_hand = -1;
  int left_shoulder = -1;
  int right_elbow = -1;
  int left_elbow = -1;
};

// A glove's calibration: per sensor (5 or 14) the raw value with the hand flat and in a fist.
struct GloveRange {
  std::vector<double> min, max;
};

enum class DepthPixels { Ir, Color };
// "ir" | "color", as the rig file spells it.
std::string_view depth_pixels_name(DepthPixels pixels);

struct Rig {
  std::filesystem::path path;  // where it was read from (empty for a built-in rig)

  // The depth sensor as it delivers frames; absent = the source's own intrinsics.
  std::optional<Intrinsics> depth;
  // The eye cameras (index by Side: 0 left, 1 right); absent = the depth's intrinsics, no
  // distortion.
  std::array<std::optional<CameraModel>, 2> eye;
  // p_right = rotation * p_left + translation_m (a calibrated stereo pair: the left eye about one
  // baseline to the left: the left eye's centre is at translation_m in the right eye's frame,
  // x ~ -baseline).
  std::optional<RigidTransform> X_RightEyeLeftEye;
  // p_right = rotation * p_depth + translation_m.
  std::optional<RigidTransform> X_RightEyeDepth;
  // The pixels X_RightEyeDepth's depth camera is: the sensor's own IR camera (extrinsics.
  // depth_pixels "ir", the default: `telex calibrate depth-eye --ir` on IR images), or its colour
  // camera ("color": calibrated on depth the sensor registered in hardware).
  DepthPixels depth_pixels = DepthPixels::Ir;

  RobotHead robot_head;

  // The operator: the right-eye camera in the head marker body's frame (Motive's: x right, y up,
  // z backward): p_HeadCamera, and the rotation head -> camera.
  glm::dvec3 p_HeadCamera{0.032, 0.0, -0.08};
  glm::dmat3 R_CameraHead{1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0};
  MarkerBodies bodies;
  // --head-source hmd: the headset's tracking space (OpenXR's STAGE, or LOCAL) in the NatNet
  // frame: p_NatNet = rotation * p_Stage + translation_m (operator.hmd_stage_in_natnet; identity
  // when the two were set up to coincide). The headset's view frame (x right, y up, z backward)
  // then stands for the head marker body's.
  RigidTransform X_NatNetStage;
  BodyDims body;
  std::array<std::optional<GloveRange>, 2> glove;  // by Side
  // Haptic display channel each finger drives (thumb first), per hand.
  std::array<std::array<int, 5>, 2> display_channel{{{0, 1, 2, 3, 4}, {0, 1, 2, 3, 4}}};
  // The virtual body's colour in the view (R, G, B).
  std::array<int, 3> skin_rgb{225, 175, 150};
  // The Gravity Grabber's settings object (docs/HARDWARE.md); null = none given. Checked by the
  // station's display, which owns its keys.
  nlohmann::json gravity_grabber;

  // The stereo baseline, |translation| of X_RightEyeLeftEye; nullopt without it.
  std::optional<double> baseline_m() const;
};

// Parses a rig from JSON text; `origin` names it in errors. Throws RigError.
Rig parse_rig(std::string_view text, const std::string& origin);
// Reads FILE; a missing file is a RigError naming the path.
Rig load_rig(const std::filesystem::path& path);
// The rig as JSON, every key written (what load_rig of the result gives back).
nlohmann::json rig_to_json(const Rig& rig);

// Merges `patch` into the rig file at `path` (RFC 7386 merge patch; the file is created when
// missing), checks the result as load_rig does and writes it atomically. Calibration commands
// write their results with this. Throws RigError when the result is not a valid rig.
void update_rig_file(const std::filesystem::path& path, const nlohmann::json& patch);

// JSON helpers for the calibration commands' patches.
nlohmann::json camera_model_json(const CameraModel& camera);
nlohmann::json transform_json(const RigidTransform& x);

// The command-line convention of both daemons: "--rig FILE" or "--rig=FILE" in argv, found before
// the flags are parsed so the rig sets the defaults and the flags given override them. nullopt
// when absent; throws RigError when --rig has no value.
std::optional<std::filesystem::path> rig_path_in_args(int argc, const char* const* argv);

}  // namespace telex
