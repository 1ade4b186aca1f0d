// SPDX-License-Identifier: MIT
// `telex body --check`: the virtual body's arm solve against arms generated forward from joint
// angles (known elbows), plus the singular and hostile inputs. Lives with the tools, like the
// haptic stability suite: it tests the haptics target's body.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "telex/haptics/body.h"

namespace telex {

struct BodyCaseResult {
  std::string name;
  bool pass = false;
  // The wrist lay within the arm's reach in every update of the case.
  bool reachable = true;
  // Largest elbow error over the case where the inputs determine the elbow (a marker or the
  // forearm axis); nullopt where they do not (posture rule) or the wrist is out of reach.
  std::optional<double> elbow_error_m;
  std::uint64_t nonfinite = 0;  // NaN/Inf in any output point
  std::uint64_t updates = 0;
  std::string criteria;
  std::string note;
};

// A ground-truth arm from joint angles: the upper arm's direction (azimuth about world up from
// the body's outward direction, elevation from horizontal), the elbow's flexion (0 = straight)
// and the swivel of the forearm about the upper arm. Returns shoulder, elbow, wrist and a wrist
// body whose forearm axis (BodyDims::forearm_axis_wrist) runs elbow -> wrist, twisted by
// `twist_rad` about it.
struct ArmTruth {
  glm::dvec3 shoulder{0.0}, elbow{0.0}, wrist{0.0};
  Pose wrist_pose;
};
ArmTruth arm_forward(const BodyDims& dims, Side side, const glm::dvec3& shoulder,
                     double azimuth_rad, double elevation_rad, double flexion_rad,
                     double swivel_rad, double twist_rad);

// Every case: at least 20 generated arms (both sides, forearm axis, elbow marker, noisy axis,
// posture rule) and the singular / hostile ones (wrist beyond reach, at the shoulder, on the
// swivel axis, NaN/Inf, missing bodies held 200 ms then hidden, far from the origin).
std::vector<BodyCaseResult> run_body_check(std::uint64_t seed = 1);

}  // namespace telex
