// SPDX-License-Identifier: MIT
// Hand kinematics: wrist pose + finger bends -> joint chain, and the head pose that maps the
// operator's space onto the robot camera's frame.
#pragma once

#include <array>
#include <cstdint>
#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>
#include <span>

namespace telex::local {

struct HandState;

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

struct HandModelConfig {
  std::array<FingerGeometry, 5> fingers = default_fingers();
  bool left = false;  // mirror the hand frame's z for a left hand
  // Camera centre in the head rigid body's frame, and the rotation head -> camera. The default
  // head frame is Motive's (x right, y up, z backward), which a camera with y down, z forward sees
  // as diag(1, -1, -1); the centre sits at the right eye, 8 cm in front of the head body.
  glm::dvec3 p_HeadCamera{0.032, 0.0, -0.08};
  glm::dmat3 R_CameraHead{1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0};

  static std::array<FingerGeometry, 5> default_fingers();
};

struct HandPoints {
  std::array<std::array<glm::dvec3, 4>, 5> joints{};  // MCP, PIP, DIP, tip
  std::array<glm::dvec3, 5> axis{};                   // distal phalanx direction (unit)
  glm::dvec3 wrist{0.0};
};

// Forward kinematics in the wrist pose's frame (world); bends are 0 (straight) .. 1 (fist),
// clamped. Pure.
HandPoints hand_forward(const HandModelConfig& config, const Pose& X_WorldWrist,
                        std::span<const double, 5> bend);

// p_CameraFingertip = R_CameraHead (R_WorldHead^T (p_WorldQ - t_head) - camera_in_head).
glm::dvec3 world_to_camera(const HandModelConfig& config, const Pose& X_WorldHead,
                           const glm::dvec3& p_WorldQ);
glm::dvec3 world_dir_to_camera(const HandModelConfig& config, const Pose& X_WorldHead,
                               const glm::dvec3& dir_World);

// Maps world hand points into `out` (camera frame), marks every tip valid and the skeleton valid.
void fill_hand_state(const HandModelConfig& config, const Pose& X_WorldHead, const HandPoints& hand,
                     std::int64_t time_ns, HandState& out);

// Fingertip velocities by finite differences against the previous state (same finger valid in
// both and a positive time step); zero otherwise.
void update_velocities(const HandState& previous, HandState& current);

}  // namespace telex::local
