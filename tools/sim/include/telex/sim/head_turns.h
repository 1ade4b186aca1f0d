// SPDX-License-Identifier: MIT
// One head motion that both simulators report, for `telex calibrate hmd` end to end: the project's
// OpenXR runtime (script "head_path": "turns") gives the headset's view at it, telex-sim-natnet
// (--motion head-turns) the head rigid body carrying that headset, through a fixed stage in the
// NatNet frame and a fixed view frame in the head body. The motion is a function of the host's
// CLOCK_MONOTONIC, so the two processes agree on it without talking to each other.
// Header-only (glm): the runtime is a shared library that links nothing of the project.
#pragma once

#include <cmath>
#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>
#include <numbers>

namespace telex::sim {

// A rigid transform X_AB: q_AB, p_AoBo_A (metres).
struct SimPose {
  glm::dquat q{1.0, 0.0, 0.0, 0.0};
  glm::dvec3 p_m{0.0};
};

inline SimPose compose(const SimPose& X_AB, const SimPose& X_BC) {
  return {glm::normalize(X_AB.q * X_BC.q), X_AB.p_m + X_AB.q * X_BC.p_m};
}

inline SimPose inverse(const SimPose& X_AB) {
  const glm::dquat q_BA = glm::conjugate(X_AB.q);
  return {q_BA, -(q_BA * X_AB.p_m)};
}

inline constexpr double kHeadTurnsDeg = std::numbers::pi / 180.0;

// The headset's VIEW in the runtime's LOCAL space (OpenXR axes: x right, y up, z backwards) at
// CLOCK_MONOTONIC time t_s: yaw +-40 deg (period 7 s), pitch +-20 deg (4.3 s), roll +-12 deg
// (3.1 s), at most 36 deg/s, and a few centimetres of sway: turns about all three axes, as
// `telex calibrate hmd` needs.
inline SimPose head_turns_view_in_local(double t_s) {
  constexpr double two_pi = 2.0 * std::numbers::pi;
  const double yaw = 40.0 * kHeadTurnsDeg * std::sin(two_pi * t_s / 7.0);
  const double pitch = 20.0 * kHeadTurnsDeg * std::sin(two_pi * t_s / 4.3 + 0.7);
  const double roll = 12.0 * kHeadTurnsDeg * std::sin(two_pi * t_s / 3.1 + 1.9);
  const glm::dquat q = glm::angleAxis(yaw, glm::dvec3(0, 1, 0)) *
                       glm::angleAxis(pitch, glm::dvec3(1, 0, 0)) *
                       glm::angleAxis(roll, glm::dvec3(0, 0, 1));
  const glm::dvec3 sway_m{0.03 * std::sin(two_pi * t_s / 5.3), 0.02 * std::sin(two_pi * t_s / 3.7),
                          0.03 * std::sin(two_pi * t_s / 6.1)};
  return {glm::normalize(q), sway_m};
}

// The runtime's LOCAL origin in its STAGE space: the head starts 1.6 m above the floor.
inline SimPose head_turns_local_in_stage() { return {{1.0, 0.0, 0.0, 0.0}, {0.0, 1.6, 0.0}}; }

// The STAGE in the NatNet frame (Motive's axes, y up): turned 35 deg about the vertical, tilted
// 2 deg, its origin 1.3 m from Motive's.
inline SimPose head_turns_stage_in_natnet() {
  const glm::dquat q = glm::angleAxis(35.0 * kHeadTurnsDeg, glm::dvec3(0, 1, 0)) *
                       glm::angleAxis(2.0 * kHeadTurnsDeg, glm::dvec3(1, 0, 0));
  return {glm::normalize(q), {1.2, 0.02, -0.5}};
}

// The headset's VIEW frame in the head rigid body (markers on top of the headset, the body's
// frame set up by hand in Motive, so not aligned with the view).
inline SimPose head_turns_view_in_body() {
  const glm::dquat q = glm::angleAxis(6.0 * kHeadTurnsDeg, glm::dvec3(1, 0, 0)) *
                       glm::angleAxis(-4.0 * kHeadTurnsDeg, glm::dvec3(0, 1, 0));
  return {glm::normalize(q), {0.01, -0.07, -0.06}};
}

// The head rigid body in the NatNet frame at t_s: X_NatNetStage X_StageLocal X_LocalView(t)
// X_ViewBody.
inline SimPose head_turns_body_in_natnet(double t_s) {
  return compose(compose(head_turns_stage_in_natnet(), head_turns_local_in_stage()),
                 compose(head_turns_view_in_local(t_s), inverse(head_turns_view_in_body())));
}

}  // namespace telex::sim
