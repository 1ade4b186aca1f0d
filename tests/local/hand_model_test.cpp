// SPDX-License-Identifier: MIT
// Hand kinematics and head-to-camera mapping against closed-form positions.
#include "telex/local/inputs/hand_model.h"

#include <gtest/gtest.h>

#include <cmath>
#include <glm/gtc/quaternion.hpp>

#include "telex/local/inputs/tracker.h"

namespace telex::local {
namespace {

void expect_near(const glm::dvec3& a, const glm::dvec3& b, double tol = 1e-9) {
  EXPECT_NEAR(a.x, b.x, tol);
  EXPECT_NEAR(a.y, b.y, tol);
  EXPECT_NEAR(a.z, b.z, tol);
}

TEST(HandModel, StraightFingersExtendAlongTheirDirection) {
  HandModelConfig cfg;
  const std::array<double, 5> bend{0, 0, 0, 0, 0};
  const HandPoints h = hand_forward(cfg, Pose{}, bend);
  for (int i = 0; i < 5; ++i) {
    const auto& g = cfg.fingers[i];
    const double len = g.segment_m[0] + g.segment_m[1] + g.segment_m[2];
    expect_near(h.joints[i][3], g.base_hand_m + glm::normalize(g.dir_hand) * len);
    expect_near(h.axis[i], glm::normalize(g.dir_hand));
  }
}

TEST(HandModel, EachJointBendsOnlyFromItsJointOn) {
  HandModelConfig cfg;
  const std::array<double, 5> half{0.5, 0.5, 0.5, 0.5, 0.5};
  JointBends equal{};
  for (auto& f : equal) f = {0.5, 0.5, 0.5};
  // Equal joint bends are the one-bend hand, exactly.
  const HandPoints a = hand_forward(cfg, Pose{}, half), b = hand_forward(cfg, Pose{}, equal);
  for (int i = 0; i < 5; ++i)
    for (int j = 0; j < 4; ++j) EXPECT_EQ(a.joints[i][j], b.joints[i][j]);
  // Bending the index's PIP alone leaves its knuckle and PIP joint where a straight finger has
  // them and moves the DIP joint and the tip.
  const HandPoints straight = hand_forward(cfg, Pose{}, std::array<double, 5>{});
  JointBends pip{};
  pip[1] = {0.0, 1.0, 0.0};
  const HandPoints p = hand_forward(cfg, Pose{}, pip);
  expect_near(p.joints[1][0], straight.joints[1][0]);
  expect_near(p.joints[1][1], straight.joints[1][1]);
  EXPECT_GT(glm::length(p.joints[1][2] - straight.joints[1][2]), 0.01);
  // The PIP angle turns the middle phalanx: (cos a, -sin a, 0) with a = max PIP angle.
  const auto& g = cfg.fingers[1];
  const double ang = g.max_angle_rad[1];
  expect_near(p.joints[1][2],
              p.joints[1][1] + glm::dvec3{std::cos(ang), -std::sin(ang), 0.0} * g.segment_m[1]);
}

TEST(HandModel, FullyBentIndexMatchesPlanarChain) {
  HandModelConfig cfg;
  const std::array<double, 5> bend{0, 1, 0, 0, 0};
  const HandPoints h = hand_forward(cfg, Pose{}, bend);
  const auto& g = cfg.fingers[1];
  // Flexion about -z rotates +x toward -y: direction at cumulative angle a is (cos a, -sin a, 0).
  glm::dvec3 p = g.base_hand_m;
  double a = 0.0;
  for (int s = 0; s < 3; ++s) {
    a += g.max_angle_rad[s];
    p += glm::dvec3{std::cos(a), -std::sin(a), 0.0} * g.segment_m[s];
  }
  expect_near(h.joints[1][3], p);
  expect_near(h.axis[1], glm::dvec3{std::cos(a), -std::sin(a), 0.0});
}

TEST(HandModel, SegmentLengthsHoldForAnyBendAndPose) {
  HandModelConfig cfg;
  Pose wrist{{0.1, 1.2, -0.3}, glm::angleAxis(0.7, glm::normalize(glm::dvec3{1, 2, 3}))};
  for (double b : {0.0, 0.25, 0.5, 0.9, 1.0}) {
    const std::array<double, 5> bend{b, b, b, b, b};
    const HandPoints h = hand_forward(cfg, wrist, bend);
    for (int i = 0; i < 5; ++i)
      for (int s = 0; s < 3; ++s)
        EXPECT_NEAR(glm::length(h.joints[i][s + 1] - h.joints[i][s]), cfg.fingers[i].segment_m[s],
                    1e-12);
  }
}

TEST(HandModel, WristRotationRotatesTheHand) {
  HandModelConfig cfg;
  const std::array<double, 5> bend{0.2, 0.4, 0.6, 0.8, 1.0};
  const HandPoints h0 = hand_forward(cfg, Pose{}, bend);
  const glm::dquat q = glm::angleAxis(glm::radians(90.0), glm::dvec3{0, 1, 0});
  const glm::dvec3 t{0.5, 0.2, -0.1};
  const HandPoints h1 = hand_forward(cfg, Pose{t, q}, bend);
  for (int i = 0; i < 5; ++i) expect_near(h1.joints[i][3], t + q * h0.joints[i][3]);
  // 90 deg about y maps x to -z: the straight index direction (+x) points along -z.
  expect_near(q * glm::dvec3{1, 0, 0}, {0, 0, -1}, 1e-12);
}

TEST(HandModel, LeftHandMirrorsAcrossThePalmPlane) {
  HandModelConfig right, left;
  left.left = true;
  const std::array<double, 5> bend{0.5, 0.3, 0.3, 0.3, 0.3};
  const HandPoints r = hand_forward(right, Pose{}, bend);
  const HandPoints l = hand_forward(left, Pose{}, bend);
  for (int i = 0; i < 5; ++i) {
    EXPECT_NEAR(l.joints[i][3].x, r.joints[i][3].x, 1e-12);
    EXPECT_NEAR(l.joints[i][3].y, r.joints[i][3].y, 1e-12);
    EXPECT_NEAR(l.joints[i][3].z, -r.joints[i][3].z, 1e-12);
  }
}

TEST(HandModel, HeadPoseMapsWorldPointsIntoTheCamera) {
  HandModelConfig cfg;
  // Head at the origin, Motive axes: 0.5 m in front of the camera is -z in the head frame.
  const glm::dvec3 ahead = cfg.p_HeadCamera + glm::dvec3{0, 0, -0.5};
  expect_near(world_to_camera(cfg, Pose{}, ahead), {0, 0, 0.5});
  // Above the camera (world +y) is image-up, camera -y.
  expect_near(world_to_camera(cfg, Pose{}, cfg.p_HeadCamera + glm::dvec3{0, 0.1, -0.5}),
              {0, -0.1, 0.5});
  // Operator turned 90 deg left (about +y) and stepped to (1, 1.6, 2): the point ahead of the
  // turned head is at -x in the world.
  const Pose head{{1.0, 1.6, 2.0}, glm::angleAxis(glm::radians(90.0), glm::dvec3{0, 1, 0})};
  const glm::dvec3 p_WorldQ = head.p_m + head.q * (cfg.p_HeadCamera + glm::dvec3{0, 0, -0.7});
  EXPECT_LT(p_WorldQ.x, head.p_m.x);
  expect_near(world_to_camera(cfg, head, p_WorldQ), {0, 0, 0.7});
  expect_near(world_dir_to_camera(cfg, head, head.q * glm::dvec3{1, 0, 0}), {1, 0, 0});
}

TEST(HandModel, FillStateAndFiniteDifferenceVelocities) {
  HandModelConfig cfg;
  const std::array<double, 5> bend{0.3, 0.3, 0.3, 0.3, 0.3};
  Pose wrist{{0.0, 1.0, -0.4}, {}};
  HandState a, b;
  fill_hand_state(cfg, Pose{}, hand_forward(cfg, wrist, bend), 1'000'000'000, a);
  wrist.p_m += glm::dvec3{0.0, 0.0, -0.002};  // 2 mm toward the scene in 1/120 s
  fill_hand_state(cfg, Pose{}, hand_forward(cfg, wrist, bend), 1'000'000'000 + 8'333'333, b);
  update_velocities(a, b);
  for (int i = 0; i < 5; ++i) {
    EXPECT_TRUE(b.tips[i].valid);
    EXPECT_EQ(b.tips[i].finger, i);
    expect_near(b.tips[i].v_CameraFingertip, {0, 0, 0.002 / 0.008333333}, 1e-6);
    EXPECT_NEAR(glm::length(b.tips[i].axis_Camera), 1.0, 1e-12);
  }
  // A time step that is not positive gives no velocity rather than infinity.
  HandState c = b;
  update_velocities(b, c);
  expect_near(c.tips[1].v_CameraFingertip, {0, 0, 0});
}

}  // namespace
}  // namespace telex::local
