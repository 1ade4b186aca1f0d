// SPDX-License-Identifier: MIT
// The robot head's orientation from its joints and back (yaw, pitch, roll about the rig's axes),
// and the operator's head as the same rotation: the station sends the operator's head as joint
// targets and places the fingertips with the joints the head measured at a frame's capture.
#pragma once

#include <array>
#include <glm/glm.hpp>

#include "telex/common/body_dims.h"
#include "telex/common/rig.h"

namespace telex {

// R_BaseCamera(q) = Rot(axis_yaw, q0) Rot(axis_pitch, q1) Rot(axis_roll, q2): the right-eye
// camera's orientation in the head base's frame (which is the camera's at zero angles). Pure.
glm::dmat3 head_rotation(const RobotHead& head, const std::array<double, 3>& joint_rad);

// The joints that give R_BaseCamera (within the principal ranges: yaw and roll in [-pi, pi],
// pitch in [-pi/2, pi/2]); the inverse of head_rotation where the axes are mutually perpendicular.
// Throws RigError naming robot_head.joints when they are not (checked by check_head_axes).
std::array<double, 3> head_joints(const RobotHead& head, const glm::dmat3& R_BaseCamera);
void check_head_axes(const RobotHead& head);

// The operator's head as the robot's camera orientation: the head base is the camera's frame when
// the head rigid body has its reference orientation (identity: as Motive defines the rigid body),
// so R_BaseCamera = R_CameraHead R_WorldHead R_CameraHead^T.
glm::dmat3 operator_head_in_base(const glm::dmat3& R_CameraHead, const Pose& X_WorldHead);

}  // namespace telex
