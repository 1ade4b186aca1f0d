// SPDX-License-Identifier: MIT
// The operator's body as the rig file describes it: segment lengths, eye offset, the hands'
// geometry. Plain data the rig (telex/common/rig.h) holds; the kinematics that use it are in the
// haptics target (telex/haptics/body.h, hand_kinematics.h).
#pragma once

#include <array>
#include <cstdint>
#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>

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

enum class Side : std::uint8_t { Left = 0, Right = 1 };
inline constexpr std::array<Side, 2> kSides{Side::Left, Side::Right};
inline std::size_t index_of(Side s) { return static_cast<std::size_t>(s); }

// The operator's body. The default is an adult of 1.75 m stature with the segment proportions of
// Drillis & Contini (1966) as tabulated in Winter, "Biomechanics and Motor Control of Human
// Movement" (4th ed., table 4.1): upper arm 0.186 H = 0.326 m, forearm 0.146 H = 0.256 m; the hand
// is HandGeometry's default; the interpupillary distance 64 mm (Dodgson 2004: adult mean 63 mm)
// with the eyes 8 cm in front of the head body, as the station's camera offset assumes.
struct BodyDims {
  double upper_arm_m = 0.186 * 1.75;  // shoulder centre to elbow centre
  double forearm_m = 0.146 * 1.75;    // elbow centre to wrist centre
  // The eyes' midpoint in the head rigid body's frame (Motive's: x right, y up, z backward).
  glm::dvec3 p_HeadEyes{0.0, 0.0, -0.08};
  double ipd_m = 0.064;
  // The forearm axis (elbow toward wrist) in the wrist rigid body's frame: with the body on the
  // back of the wrist, along the fingers' straight direction.
  glm::dvec3 forearm_axis_wrist{1.0, 0.0, 0.0};
  // false when the wrist body sits on the hand (which flexes at the wrist): its orientation then
  // says nothing of the forearm, and without an elbow marker the posture rule picks the elbow.
  bool forearm_axis_from_wrist = true;
  // World up (Motive: +y). The posture rule pulls the elbow down, out and back; its one
  // undetermined direction (the pole) is the arm pointing that way, down and behind the body,
  // outside a teleoperator's working space in front.
  glm::dvec3 up_world{0.0, 1.0, 0.0};
  double elbow_out_weight = 0.35;  // how far "out" pulls the elbow against "down"
  double elbow_back_weight = 0.5;  // how far "back" pulls it
  // The posture rule's swivel turns at most this fast (rad/s): near the pole, where the rule's
  // direction swings round, the elbow turns at a natural pace instead of flipping.
  double swivel_rate_rad_s = 3.0;
  // An arm whose inputs are missing or not finite keeps its last pose this long, then is hidden.
  double hold_s = 0.2;
  std::array<HandGeometry, 2> hands{left_hand(), HandGeometry{}};  // by Side

  static HandGeometry left_hand() {
    HandGeometry h;
    h.left = true;
    return h;
  }
  // Throws std::invalid_argument naming the field when a length or time is not finite and
  // positive or a direction is zero.
  void validate() const;
};

}  // namespace telex
