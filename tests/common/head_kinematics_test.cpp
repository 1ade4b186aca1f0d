// SPDX-License-Identifier: MIT
// Robot head joints <-> orientation: the round trip, the axes' meaning, the operator's head.
#include "telex/common/head_kinematics.h"

#include <gtest/gtest.h>

#include <glm/gtc/matrix_transform.hpp>
#include <random>

namespace telex {
namespace {

double max_abs(const glm::dmat3& m) {
  double w = 0;
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) w = std::max(w, std::abs(m[c][r]));
  return w;
}

TEST(HeadKinematics, JointsToOrientationAndBackOverTheWholeRange) {
  RobotHead head;  // yaw about -y (up), pitch about x, roll about z
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> yaw(-3.0, 3.0), pitch(-1.5, 1.5), roll(-3.0, 3.0);
  for (int i = 0; i < 500; ++i) {
    const std::array<double, 3> q{yaw(rng), pitch(rng), roll(rng)};
    const auto back = head_joints(head, head_rotation(head, q));
    for (int j = 0; j < 3; ++j) EXPECT_NEAR(back[j], q[j], 1e-9) << i << " joint " << j;
  }
  // A rig whose roll axis points the other way reads roll with the other sign.
  RobotHead flipped = head;
  flipped.joints[2].axis = -flipped.joints[2].axis;
  const auto q = head_joints(flipped, head_rotation(flipped, {0.2, -0.1, 0.3}));
  EXPECT_NEAR(q[2], 0.3, 1e-9);
}

TEST(HeadKinematics, PositiveYawTurnsTheCameraLeftAndPositivePitchUp) {
  RobotHead head;
  const glm::dvec3 fwd{0, 0, 1};
  const glm::dvec3 yawed = head_rotation(head, {0.3, 0, 0}) * fwd;
  EXPECT_LT(yawed.x, -0.2);  // camera x is right: forward swung left
  const glm::dvec3 pitched = head_rotation(head, {0, 0.3, 0}) * fwd;
  EXPECT_LT(pitched.y, -0.2);  // camera y is down: forward swung up
}

TEST(HeadKinematics, TheOperatorsHeadIsTheCamerasOrientationInTheBase) {
  const Rig rig;
  // The operator turns 20 degrees to the left: about Motive's +y (up).
  Pose head;
  head.q = glm::angleAxis(0.349065850, glm::dvec3(0, 1, 0));
  const glm::dmat3 R = operator_head_in_base(rig.R_CameraHead, head);
  const auto q = head_joints(rig.robot_head, R);
  EXPECT_NEAR(q[0], 0.349065850, 1e-9);  // yaw left, as the head's yaw axis says
  EXPECT_NEAR(q[1], 0.0, 1e-9);
  EXPECT_NEAR(q[2], 0.0, 1e-9);
  EXPECT_LT(max_abs(operator_head_in_base(rig.R_CameraHead, Pose{}) - glm::dmat3(1.0)), 1e-12);
}

TEST(HeadKinematics, AxesThatAreNotPerpendicularAreARigError) {
  RobotHead head;
  head.joints[1].axis = glm::normalize(glm::dvec3(1, 0.2, 0));
  EXPECT_THROW(head_joints(head, glm::dmat3(1.0)), RigError);
}

}  // namespace
}  // namespace telex
