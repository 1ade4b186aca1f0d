// SPDX-License-Identifier: MIT
// The body check suite (`telex stability`'s arms): every case passes, and it catches a wrong arm.
#include "telex/stability/body_check.h"

#include <gtest/gtest.h>

namespace telex {
namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;

TEST(BodyCheck, EveryCasePassesWithTwentyDeterminedElbowsWithinOneCentimetre) {
  const auto cases = run_body_check(1);
  int determined = 0;
  for (const auto& c : cases) {
    EXPECT_TRUE(c.pass) << c.name << ": " << c.criteria << " / " << c.note;
    EXPECT_EQ(c.nonfinite, 0u) << c.name;
    if (c.elbow_error_m) {
      ++determined;
      EXPECT_LE(*c.elbow_error_m, 0.01) << c.name;
    }
  }
  EXPECT_GE(determined, 20);
  EXPECT_GE(cases.size(), 30u);
}

TEST(BodyCheck, AWrongArmLengthIsCaught) {
  // The check's generator and the solver share BodyDims; a solver told the wrong forearm cannot
  // put the elbow where the generated one is. This is the error the check exists to find.
  BodyDims truth_dims, wrong = truth_dims;
  wrong.forearm_m *= 1.1;
  const ArmTruth t = arm_forward(truth_dims, Side::Right, {0.18, 1.45, 0.0}, 50 * kDeg, -20 * kDeg,
                                 70 * kDeg, 30 * kDeg, 0.0);
  ArmSolveInput in;
  in.shoulder = t.shoulder;
  in.wrist = t.wrist;
  in.forearm_axis = glm::normalize(t.wrist - t.elbow);
  const ArmSolution s = solve_arm(wrong.upper_arm_m, wrong.forearm_m, in);
  EXPECT_GT(glm::length(s.elbow - t.elbow), 0.01);
}

}  // namespace
}  // namespace telex
