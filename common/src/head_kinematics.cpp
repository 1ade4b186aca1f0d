// SPDX-License-Identifier: MIT
// Robot head joints <-> orientation, and the operator's head in the head base's frame.
#include "telex/common/head_kinematics.h"

#include <cmath>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtx/euler_angles.hpp>

namespace telex {
namespace {

glm::dmat3 rot(const glm::dvec3& axis, double angle) {
  return glm::dmat3(glm::rotate(glm::dmat4(1.0), angle, axis));
}

}  // namespace

glm::dmat3 head_rotation(const RobotHead& head, const std::array<double, 3>& q) {
  return rot(head.joints[0].axis, q[0]) * rot(head.joints[1].axis, q[1]) *
         rot(head.joints[2].axis, q[2]);
}

void check_head_axes(const RobotHead& head) {
  const glm::dvec3 &a = head.joints[0].axis, &b = head.joints[1].axis, &c = head.joints[2].axis;
  if (std::abs(glm::dot(a, b)) > 1e-6 || std::abs(glm::dot(b, c)) > 1e-6 ||
      std::abs(glm::dot(a, c)) > 1e-6)
    throw RigError(
        "rig robot_head.joints: the yaw, pitch and roll axes must be mutually perpendicular "
        "(this build turns a head pose into joints only for such heads)");
}

std::array<double, 3> head_joints(const RobotHead& head, const glm::dmat3& R) {
  check_head_axes(head);
  // In the frame B = [pitch axis, yaw axis, pitch x yaw] the chain is the standard Y-X-Z one:
  // B^T R B = Ry(yaw) Rx(pitch) Rz(s roll), with s = +-1 as the roll axis is +-(pitch x yaw).
  const glm::dvec3 x = head.joints[1].axis, y = head.joints[0].axis, z = glm::cross(x, y);
  const glm::dmat3 B(x, y, z);  // columns
  const glm::dmat3 Rp = glm::transpose(B) * R * B;
  double yaw = 0.0, pitch = 0.0, roll = 0.0;
  glm::extractEulerAngleYXZ(glm::dmat4(Rp), yaw, pitch, roll);
  const double s = glm::dot(head.joints[2].axis, z) > 0.0 ? 1.0 : -1.0;
  return {yaw, pitch, s * roll};
}

glm::dmat3 operator_head_in_base(const glm::dmat3& R_CameraHead, const Pose& X_WorldHead) {
  return R_CameraHead * glm::mat3_cast(X_WorldHead.q) * glm::transpose(R_CameraHead);
}

}  // namespace telex
