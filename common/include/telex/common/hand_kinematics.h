// SPDX-License-Identifier: MIT
// Hand forward kinematics: a wrist pose and finger bends give the finger joints. Pure; used by the
// station's hand tracker and by the body (telex/common/body.h).
#pragma once

#include <array>
#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>
#include <span>

namespace telex {

// A rigid pose in the tracking system's world frame: p_WorldQ = q * p_body + p_m.
struct Pose {
  glm::dvec3 p_m{0.0};
  glm::dquat q{1.0, 0.0, 0.0, 0.0};  // w, x, y, z
};

// One finger in the hand frame. The hand frame (origin at the wrist rigid body): +x along the
// fingers, +y out of the back of the hand, z = x cross y (toward the little finger on a right
// hand; mirrored for a left hand).
struct FingerGeometry {
  glm::dvec3 base_hand_m{0.0};                            // knuckle (MCP) position
  glm::dvec3 dir_hand{1.0, 0.0, 0.0};                     // straight-finger direction
  glm::dvec3 curl_toward_hand{0.0, -1.0, 0.0};            // bending rotates dir toward this
  std::array<double, 3> segment_m{0.045, 0.025, 0.022};   // proximal, middle, distal
  std::array<double, 3> max_angle_rad{1.57, 1.75, 1.22};  // MCP, PIP, DIP at bend 1
};

struct HandGeometry {
  std::array<FingerGeometry, 5> fingers = default_fingers();
  bool left = false;  // mirror the hand frame's z for a left hand

  static std::array<FingerGeometry, 5> default_fingers();
};

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
