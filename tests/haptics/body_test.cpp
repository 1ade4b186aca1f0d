// SPDX-License-Identifier: MIT
// The virtual body: the arm solve against arms generated from joint angles, the posture rule's
// continuity, the hold-then-hide of lost bodies and the eyes. Arms come from the stability suite's
// generator (telex/stability/body_check.h); the suite's own verdicts are tested in tests/tools.
#include "telex/haptics/body.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "telex/stability/body_check.h"

namespace telex {
namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;

BodyInputs both_arms(const ArmTruth& right, const ArmTruth& left, std::int64_t t_ns) {
  BodyInputs in;
  in.time_ns = t_ns;
  in.head = Pose{{0.0, 1.65, 0.0}, {1.0, 0.0, 0.0, 0.0}};
  in.shoulder[index_of(Side::Right)] = Pose{right.shoulder, {1.0, 0.0, 0.0, 0.0}};
  in.shoulder[index_of(Side::Left)] = Pose{left.shoulder, {1.0, 0.0, 0.0, 0.0}};
  in.wrist[index_of(Side::Right)] = right.wrist_pose;
  in.wrist[index_of(Side::Left)] = left.wrist_pose;
  return in;
}

TEST(ArmSolve, ElbowFromTheForearmAxisIsTheGeneratedElbow) {
  const BodyDims dims;
  Body body(dims);
  for (int k = 0; k < 50; ++k) {
    const double az = (-30.0 + 2.5 * k) * kDeg, el = (-60.0 + 2.0 * k) * kDeg;
    const double flex = (20.0 + 2.0 * k) * kDeg, swivel = (-20.0 + 2.8 * k) * kDeg;
    const ArmTruth r = arm_forward(dims, Side::Right, {0.18, 1.45, 0.0}, az, el, flex, swivel, 0.4);
    const ArmTruth l =
        arm_forward(dims, Side::Left, {-0.18, 1.45, 0.0}, az, el, flex, swivel, -0.4);
    const BodyState& s = body.update(both_arms(r, l, k * std::int64_t{10'000'000}));
    for (Side side : kSides) {
      const ArmState& a = s.arms[index_of(side)];
      const ArmTruth& t = side == Side::Right ? r : l;
      ASSERT_TRUE(a.visible);
      EXPECT_EQ(a.elbow_from, ElbowFrom::ForearmAxis);
      EXPECT_TRUE(a.reachable);
      EXPECT_LT(glm::length(a.elbow - t.elbow), 1e-9) << k;
      EXPECT_NEAR(glm::length(a.elbow - a.shoulder), dims.upper_arm_m, 1e-12);
      EXPECT_NEAR(glm::length(a.wrist - a.elbow), dims.forearm_m, 1e-12);
    }
  }
}

TEST(ArmSolve, AnElbowMarkerWinsOverTheForearmAxis) {
  const BodyDims dims;
  const ArmTruth t =
      arm_forward(dims, Side::Right, {0.18, 1.45, 0.0}, 40 * kDeg, -10 * kDeg, 80 * kDeg, 0.0, 0);
  ArmSolveInput in;
  in.shoulder = t.shoulder;
  in.wrist = t.wrist;
  // A forearm axis that points somewhere else, and a marker 3 cm off the true elbow, outward.
  in.forearm_axis = glm::normalize(glm::dvec3{0.0, 1.0, 0.0});
  const glm::dvec3 n = glm::normalize(t.wrist - t.shoulder);
  glm::dvec3 off = t.elbow - t.shoulder;
  off -= n * glm::dot(off, n);
  in.elbow_marker = t.elbow + glm::normalize(off) * 0.03;
  const ArmSolution s = solve_arm(dims.upper_arm_m, dims.forearm_m, in);
  EXPECT_EQ(s.from, ElbowFrom::Marker);
  EXPECT_LT(glm::length(s.elbow - t.elbow), 1e-9);
}

TEST(ArmSolve, OutOfReachPointsTheArmAtTheWristAndNothingIsNaN) {
  const double l1 = 0.3, l2 = 0.25;
  ArmSolveInput in;
  in.shoulder = {0.0, 0.0, 0.0};
  in.wrist = {0.0, 0.0, -2.0};
  ArmSolution s = solve_arm(l1, l2, in);
  EXPECT_FALSE(s.reachable);
  EXPECT_EQ(s.from, ElbowFrom::Straight);
  EXPECT_NEAR(s.elbow.z, -2.0 * l1 / (l1 + l2), 1e-12);
  EXPECT_NEAR(glm::length(glm::dvec2(s.elbow.x, s.elbow.y)), 0.0, 1e-12);
  // The wrist at the shoulder: the arm folds along the last (or the posture) axis.
  in.wrist = in.shoulder;
  s = solve_arm(l1, l2, in);
  EXPECT_FALSE(s.reachable);
  EXPECT_TRUE(std::isfinite(s.elbow.x) && std::isfinite(s.elbow.y) && std::isfinite(s.elbow.z));
  EXPECT_NEAR(glm::length(s.elbow), l1, 1e-9);
  // Equal segments, wrist at the shoulder: still finite.
  s = solve_arm(0.3, 0.3, in);
  EXPECT_TRUE(std::isfinite(s.elbow.x) && std::isfinite(s.elbow.y) && std::isfinite(s.elbow.z));
}

TEST(ArmSolve, PostureRuleHangsTheElbowAndTurnsSmoothlyThroughItsPole) {
  BodyDims dims;
  dims.forearm_axis_from_wrist = false;
  Body body(dims);
  const glm::dvec3 shoulder{0.18, 1.45, 0.0};
  // Reaching forward at shoulder height: the elbow hangs below the shoulder-wrist line.
  ArmTruth t;
  t.shoulder = shoulder;
  t.wrist = shoulder + glm::dvec3{0.05, -0.05, -0.45};
  t.wrist_pose = {t.wrist, {1.0, 0.0, 0.0, 0.0}};
  ArmTruth left = t;
  left.shoulder = {-0.18, 1.45, 0.0};
  left.wrist = left.shoulder + glm::dvec3{-0.05, -0.05, -0.45};
  left.wrist_pose.p_m = left.wrist;
  const BodyState& s = body.update(both_arms(t, left, 0));
  const ArmState& a = s.arms[index_of(Side::Right)];
  EXPECT_EQ(a.elbow_from, ElbowFrom::Posture);
  EXPECT_LT(a.elbow.y, (t.shoulder.y + t.wrist.y) / 2.0);
  // Sweep the wrist exactly through the pole: the elbow never jumps.
  const glm::dvec3 pole = glm::normalize(body.posture_pull(Side::Right, {1.0, 0.0, 0.0})) * 0.5;
  const glm::dvec3 across = glm::normalize(glm::cross(pole, glm::dvec3{0.0, 0.0, 1.0})) * 0.2;
  glm::dvec3 last{0.0};
  double worst = 0.0;
  for (int k = 0; k <= 400; ++k) {
    t.wrist = shoulder + pole - across + across * (2.0 * k / 400.0);
    t.wrist_pose.p_m = t.wrist;
    const glm::dvec3 e = body.update(both_arms(t, left, (k + 1) * std::int64_t{10'000'000}))
                             .arms[index_of(Side::Right)]
                             .elbow;
    if (k > 0) worst = std::max(worst, glm::length(e - last));
    last = e;
  }
  EXPECT_LT(worst, 0.01);
}

TEST(Body, LostInputsAreHeldFor200MsThenHidden) {
  const BodyDims dims;
  Body body(dims);
  const ArmTruth r = arm_forward(dims, Side::Right, {0.18, 1.45, 0.0}, 1.0, 0.0, 1.0, 0.5, 0.0);
  const ArmTruth l = arm_forward(dims, Side::Left, {-0.18, 1.45, 0.0}, 1.0, 0.0, 1.0, 0.5, 0.0);
  body.update(both_arms(r, l, 0));
  const glm::dvec3 elbow = body.state().arms[index_of(Side::Right)].elbow;
  BodyInputs lost = both_arms(r, l, 150'000'000);
  lost.wrist[index_of(Side::Right)]->p_m.x = std::numeric_limits<double>::quiet_NaN();
  const BodyState& s1 = body.update(lost);
  EXPECT_TRUE(s1.arms[index_of(Side::Right)].visible);
  EXPECT_TRUE(s1.arms[index_of(Side::Right)].held);
  EXPECT_EQ(s1.arms[index_of(Side::Right)].elbow, elbow);
  EXPECT_FALSE(s1.arms[index_of(Side::Left)].held);  // the other arm is unaffected
  lost.time_ns = 200'000'000;
  EXPECT_TRUE(body.update(lost).arms[index_of(Side::Right)].visible);
  lost.time_ns = 201'000'000;
  EXPECT_FALSE(body.update(lost).arms[index_of(Side::Right)].visible);
  EXPECT_TRUE(body.update(both_arms(r, l, 300'000'000)).arms[index_of(Side::Right)].visible);
  // Never seen: hidden from the start.
  Body fresh(dims);
  BodyInputs none;
  EXPECT_FALSE(fresh.update(none).arms[index_of(Side::Left)].visible);
}

TEST(Body, EyesSitAnIpdApartAndHandsAreMirrored) {
  BodyDims dims;
  dims.ipd_m = 0.062;
  Body body(dims);
  BodyInputs in;
  // Head turned 90 degrees to the left about up.
  in.head = Pose{{1.0, 1.7, 2.0}, glm::angleAxis(90 * kDeg, glm::dvec3{0.0, 1.0, 0.0})};
  const BodyState& s = body.update(in);
  ASSERT_TRUE(s.head_valid);
  EXPECT_NEAR(glm::length(s.eye[0] - s.eye[1]), 0.062, 1e-12);
  // Turned left, the right eye lies toward -z (forward of the original), the left toward +z.
  EXPECT_LT(s.eye[index_of(Side::Right)].z, s.eye[index_of(Side::Left)].z);
  // Same wrist pose: the left hand's thumb is on the other side of the hand (mirrored z).
  const ArmTruth r = arm_forward(dims, Side::Right, {0.18, 1.45, 0.0}, 1.0, 0.0, 1.0, 0.5, 0.0);
  BodyInputs both = both_arms(r, r, 0);
  both.shoulder[index_of(Side::Left)]->p_m = {-0.18, 1.45, 0.0};
  const BodyState& h = body.update(both);
  const glm::dvec3 thumb_r =
      glm::inverse(r.wrist_pose.q) * (h.arms[index_of(Side::Right)].hand.joints[0][3] - r.wrist);
  const glm::dvec3 thumb_l =
      glm::inverse(r.wrist_pose.q) * (h.arms[index_of(Side::Left)].hand.joints[0][3] - r.wrist);
  EXPECT_NEAR(thumb_r.z, -thumb_l.z, 1e-12);
  EXPECT_GT(std::abs(thumb_r.z), 0.01);
}

TEST(Body, BadDimensionsNameTheirField) {
  BodyDims d;
  d.forearm_m = -0.2;
  try {
    Body b(d);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("forearm_m"), std::string::npos) << e.what();
  }
  d = {};
  d.up_world = {0.0, 0.0, 0.0};
  EXPECT_THROW(Body{d}, std::invalid_argument);
  d = {};
  d.hold_s = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(Body{d}, std::invalid_argument);
}

}  // namespace
}  // namespace telex
