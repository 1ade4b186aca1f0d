// SPDX-License-Identifier: MIT
// Hand forward kinematics: a wrist pose and finger bends give the finger joints. Pure; used by the
// station's hand tracker and by the body (telex/haptics/body.h).
#pragma once

#include <array>
#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>
#include <span>

#include "telex/common/body_dims.h"

namespace telex {

struct HandPoints {
  std::array<std::array<glm::dvec3, 4>, 5> joints{};  // MCP, PIP, DIP, tip
  std::array<glm::dvec3, 5> axis{};                   // distal phalanx direction (unit)
  glm::dvec3 wrist{0.0};
};

// Per finger (thumb first), the bend of each joint: MCP, PIP, DIP, 0 (straight) .. 1 (the
// joint's max_angle_rad).
using JointBends = std::array<std::array<double, 3>, 5>;

// Forward kinematics in the wrist pose's frame (world); bends are clamped to 0..1 (NaN counts as
// 0). Pure.
HandPoints hand_forward(const HandGeometry& hand, const Pose& X_WorldWrist, const JointBends& bend);
// One bend per finger for all three of its joints (a 5-sensor glove, scripted hands).
HandPoints hand_forward(const HandGeometry& hand, const Pose& X_WorldWrist,
                        std::span<const double, 5> bend);

}  // namespace telex
