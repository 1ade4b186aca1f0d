// SPDX-License-Identifier: MIT
// Hand kinematics: wrist pose + finger bends -> joint chain, and the head pose that maps the
// operator's space onto the robot camera's frame.
#pragma once

#include <array>
#include <cstdint>
#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>
#include <span>

#include "telex/common/rig.h"
#include "telex/haptics/hand_kinematics.h"

namespace telex::local {

struct HandState;

using telex::FingerGeometry;
using telex::hand_forward;
using telex::HandPoints;
using telex::JointBends;
using telex::Pose;

// The hand's geometry (telex/haptics/hand_kinematics.h) and where the camera sits on the head.
struct HandModelConfig : HandGeometry {
  // Camera centre in the head rigid body's frame, and the rotation head -> camera. The default
  // head frame is Motive's (x right, y up, z backward), which a camera with y down, z forward sees
  // as diag(1, -1, -1); the centre sits at the right eye, 8 cm in front of the head body.
  glm::dvec3 p_HeadCamera{0.032, 0.0, -0.08};
  glm::dmat3 R_CameraHead{1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0};
};

// p_CameraFingertip = R_CameraHead (R_WorldHead^T (p_WorldQ - t_head) - camera_in_head).
glm::dvec3 world_to_camera(const HandModelConfig& config, const Pose& X_WorldHead,
                           const glm::dvec3& p_WorldQ);
glm::dvec3 world_dir_to_camera(const HandModelConfig& config, const Pose& X_WorldHead,
                               const glm::dvec3& dir_World);

// Maps world hand points into `out` (camera frame), marks every tip valid and the skeleton valid.
void fill_hand_state(const HandModelConfig& config, const Pose& X_WorldHead, const HandPoints& hand,
                     std::int64_t time_ns, HandState& out);

// The rotation that takes a point in the camera of the operator's head (hand.R_BaseCamera) into
// the camera of a frame captured with the robot head at `joint_rad`: R(joints)^T R_BaseCamera (the
// camera turns about its centre; a 3-DOF head does not follow the operator's head translation).
// Identity when the hand has no head or the frame no head reading.
glm::dmat3 capture_correction(const RobotHead& head, const HandState& hand, bool frame_head_valid,
                              const std::array<double, 3>& joint_rad);
// Applies capture_correction to the fingertips (positions, velocities, axes) and joints.
void to_capture_camera(const glm::dmat3& correction, HandState& hand);

// Fingertip velocities by finite differences against the previous state (same finger valid in
// both and a positive time step); zero otherwise.
void update_velocities(const HandState& previous, HandState& current);

}  // namespace telex::local
