// SPDX-License-Identifier: MIT
// The head-to-camera mapping of the hand (its kinematics: telex/haptics/hand_kinematics.h).
#include "telex/local/inputs/hand_model.h"

#include <algorithm>
#include <glm/gtc/quaternion.hpp>

#include "telex/common/head_kinematics.h"
#include "telex/local/inputs/hand_state.h"

namespace telex::local {

glm::dvec3 world_to_camera(const HandModelConfig& config, const Pose& X_WorldHead,
                           const glm::dvec3& p_WorldQ) {
  const glm::dvec3 p_head = glm::inverse(X_WorldHead.q) * (p_WorldQ - X_WorldHead.p_m);
  return config.R_CameraHead * (p_head - config.p_HeadCamera);
}

glm::dvec3 world_dir_to_camera(const HandModelConfig& config, const Pose& X_WorldHead,
                               const glm::dvec3& dir_World) {
  return config.R_CameraHead * (glm::inverse(X_WorldHead.q) * dir_World);
}

void fill_hand_state(const HandModelConfig& config, const Pose& X_WorldHead, const HandPoints& hand,
                     std::int64_t time_ns, HandState& out) {
  out.time_ns = time_ns;
  out.wrist_camera = world_to_camera(config, X_WorldHead, hand.wrist);
  for (int i = 0; i < kFingerCount; ++i) {
    for (int j = 0; j < 4; ++j)
      out.joints_camera[i][j] = world_to_camera(config, X_WorldHead, hand.joints[i][j]);
    Fingertip& tip = out.tips[i];
    tip.finger = i;
    tip.p_CameraFingertip = out.joints_camera[i][3];
    tip.axis_Camera = world_dir_to_camera(config, X_WorldHead, hand.axis[i]);
    tip.valid = true;
  }
  out.skeleton_valid = true;
}

void update_velocities(const HandState& previous, HandState& current) {
  const double dt_s = static_cast<double>(current.time_ns - previous.time_ns) * 1e-9;
  for (int i = 0; i < kFingerCount; ++i) {
    Fingertip& tip = current.tips[i];
    const Fingertip& old = previous.tips[i];
    tip.v_CameraFingertip = (tip.valid && old.valid && dt_s > 0.0)
                                ? (tip.p_CameraFingertip - old.p_CameraFingertip) / dt_s
                                : glm::dvec3{0.0};
  }
}

glm::dmat3 capture_correction(const RobotHead& head, const HandState& hand, bool frame_head_valid,
                              const std::array<double, 3>& joint_rad) {
  if (!hand.head_valid || !frame_head_valid) return glm::dmat3(1.0);
  return glm::transpose(head_rotation(head, joint_rad)) * hand.R_BaseCamera;
}

void to_capture_camera(const glm::dmat3& c, HandState& hand) {
  for (auto& t : hand.tips) {
    t.p_CameraFingertip = c * t.p_CameraFingertip;
    t.v_CameraFingertip = c * t.v_CameraFingertip;
    t.axis_Camera = c * t.axis_Camera;
  }
  for (auto& finger : hand.joints_camera)
    for (auto& j : finger) j = c * j;
  hand.wrist_camera = c * hand.wrist_camera;
}

}  // namespace telex::local
