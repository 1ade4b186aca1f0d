// SPDX-License-Identifier: MIT
// Hand kinematics: finger chains bent about per-finger axes, and the head-to-camera mapping.
#include "telex/local/hand_model.h"

#include <algorithm>
#include <glm/gtc/quaternion.hpp>

#include "telex/local/tracker.h"

namespace telex::local {

std::array<FingerGeometry, 5> HandModelConfig::default_fingers() {
  // Adult hand proportions (Buryanov & Kotiuk 2010, rounded); knuckles spread across z.
  std::array<FingerGeometry, 5> f{};
  f[0].base_hand_m = {0.025, -0.015, -0.030};
  f[0].dir_hand = glm::normalize(glm::dvec3{0.6, -0.2, -0.75});
  f[0].curl_toward_hand = glm::normalize(glm::dvec3{0.3, -0.6, 0.7});
  f[0].segment_m = {0.045, 0.032, 0.027};
  f[0].max_angle_rad = {0.87, 1.05, 1.22};
  f[1].base_hand_m = {0.085, 0.0, -0.025};
  f[1].segment_m = {0.044, 0.025, 0.022};
  f[2].base_hand_m = {0.088, 0.0, -0.005};
  f[2].segment_m = {0.048, 0.030, 0.024};
  f[3].base_hand_m = {0.083, 0.0, 0.015};
  f[3].segment_m = {0.045, 0.028, 0.023};
  f[4].base_hand_m = {0.075, 0.0, 0.033};
  f[4].segment_m = {0.036, 0.020, 0.020};
  return f;
}

namespace {
glm::dvec3 mirror(const glm::dvec3& v, bool left) { return left ? glm::dvec3{v.x, v.y, -v.z} : v; }
}  // namespace

HandPoints hand_forward(const HandModelConfig& config, const Pose& X_WorldWrist,
                        std::span<const double, 5> bend) {
  HandPoints out;
  out.wrist = X_WorldWrist.p_m;
  for (int i = 0; i < 5; ++i) {
    const FingerGeometry& g = config.fingers[i];
    const glm::dvec3 dir0 = glm::normalize(mirror(g.dir_hand, config.left));
    glm::dvec3 axis = glm::cross(dir0, mirror(g.curl_toward_hand, config.left));
    // A curl direction parallel to the finger leaves no bending plane: keep the finger straight.
    const double axis_len = glm::length(axis);
    axis = axis_len > 1e-9 ? axis / axis_len : glm::dvec3{0.0};
    const double b = std::clamp(bend[i], 0.0, 1.0);
    glm::dvec3 p = mirror(g.base_hand_m, config.left);
    glm::dvec3 dir = dir0;
    double angle = 0.0;
    out.joints[i][0] = X_WorldWrist.p_m + X_WorldWrist.q * p;
    for (int s = 0; s < 3; ++s) {
      angle += b * g.max_angle_rad[s];
      dir = axis_len > 1e-9 ? glm::angleAxis(angle, axis) * dir0 : dir0;
      p += dir * g.segment_m[s];
      out.joints[i][s + 1] = X_WorldWrist.p_m + X_WorldWrist.q * p;
    }
    out.axis[i] = glm::normalize(X_WorldWrist.q * dir);
  }
  return out;
}

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

HandTracker::~HandTracker() = default;

}  // namespace telex::local
