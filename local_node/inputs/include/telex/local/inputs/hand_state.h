// SPDX-License-Identifier: MIT
// What every part of the station reads of the operator's hands: the fingertips, the tracked arms
// and rigid bodies, the head, in the remote camera's frame (HandState). The trackers fill it
// (tracker.h); the surface stage, the haptic loop, the view and the recorder read it.
#pragma once

#include <array>
#include <cstdint>
#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>

#include "telex/common/rig.h"

namespace telex::local {

inline constexpr int kFingerCount = 5;  // 0 thumb, 1 index, 2 middle, 3 ring, 4 little

struct Fingertip {
  int finger = 0;
  glm::dvec3 p_CameraFingertip{0.0};
  glm::dvec3 v_CameraFingertip{0.0};
  // Unit vector along the distal phalanx, pointing out of the fingertip: shear "along the finger"
  // is measured against it.
  glm::dvec3 axis_Camera{0.0, 0.0, 1.0};
  bool valid = false;
};

// A rigid body exactly as the tracking system reported it, in the tracker's own world frame.
struct TrackedBody {
  std::int32_t id = -1;
  glm::dvec3 p_m{0.0};
  glm::dquat q{1.0, 0.0, 0.0, 0.0};  // w, x, y, z
  bool valid = false;                // tracked in this frame
};
inline constexpr int kMaxTrackedBodies = 8;

// One arm as tracked, in the remote camera frame, for the view's body (both arms are drawn; the
// haptic fingertips are those of HandState::tips).
struct ArmTrack {
  bool wrist_valid = false;
  bool wrist_orientation = false;  // X_CameraWrist.q is measured (a NatNet hand body)
  Pose X_CameraWrist;              // the hand (wrist) rigid body
  bool shoulder_valid = false, elbow_valid = false;
  glm::dvec3 p_CameraShoulder{0.0}, p_CameraElbow{0.0};
  // Per finger: MCP, PIP, DIP, tip (valid with wrist_valid).
  std::array<std::array<glm::dvec3, 4>, kFingerCount> joints_camera{};
};

// One tracker sample, everything in the remote camera frame (x right, y down, z forward, metres).
struct HandState {
  // When the sample was taken, on the caller's clock (poll's now_ns); with NatNet, the poll that
  // took the newest accepted mocap frame (a glove-only update does not make old poses new).
  std::int64_t time_ns = 0;
  // When the poses in it were sampled, CLOCK_MONOTONIC ns, the start of the view's motion to
  // photon: NatNet's mid-exposure (the frame's arrival less the latency the server reports), or
  // with --head-source hmd the older of that and the headset pose's; a script's poll; a glove
  // report's arrival. 0: not known.
  std::int64_t motion_ns = 0;
  std::array<Fingertip, kFingerCount> tips{};
  // Joint chain per finger for drawing: knuckle (MCP), PIP, DIP, tip. Valid when skeleton_valid.
  std::array<std::array<glm::dvec3, 4>, kFingerCount> joints_camera{};
  glm::dvec3 wrist_camera{0.0};
  glm::dvec3 shoulder_camera{0.0};  // valid when shoulder_valid (NatNet with a shoulder body)
  bool skeleton_valid = false;
  bool shoulder_valid = false;
  // Both arms by Side (telex/haptics/body.h: 0 left, 1 right), NatNet only; the haptic hand's arm
  // repeats wrist_camera and shoulder_camera with the wrist's orientation and an elbow marker.
  std::array<ArmTrack, 2> arms{};
  // The operator's head as the robot camera's orientation in the head base's frame
  // (operator_head_in_base; NatNet with a head body): the fingertips above are in this camera.
  // The station sends it to the remote as head joints and, given a surface captured with the
  // robot head elsewhere, turns the fingertips into that surface's camera.
  bool head_valid = false;
  glm::dmat3 R_BaseCamera{1.0};
  // Raw rigid bodies behind this state (NatNet only; body_count 0 for scripts and gloves), logged
  // by --log-tracking.
  std::array<TrackedBody, kMaxTrackedBodies> bodies{};
  int body_count = 0;
  bool bodies_fresh = false;  // the bodies come from a new tracker frame
  // When the NatNet frame behind `bodies` was seen (its mid-exposure, CLOCK_MONOTONIC ns), whatever
  // the head source: --record-hmd-poses pairs the head body with the headset by it. 0: not known.
  std::int64_t bodies_sampled_ns = 0;
};

}  // namespace telex::local
