// SPDX-License-Identifier: MIT
// Hand forward kinematics: finger chains bent about per-finger axes.
#include "telex/haptics/hand_kinematics.h"

#include <algorithm>
#include <cmath>

namespace telex {

namespace {
glm::dvec3 mirror(const glm::dvec3& v, bool left) { return left ? glm::dvec3{v.x, v.y, -v.z} : v; }
}  // namespace

HandPoints hand_forward(const HandGeometry& hand, const Pose& X_WorldWrist,
                        std::span<const double, 5> bend) {
  JointBends joints{};
  for (std::size_t f = 0; f < 5; ++f) joints[f] = {bend[f], bend[f], bend[f]};
  return hand_forward(hand, X_WorldWrist, joints);
}

HandPoints hand_forward(const HandGeometry& hand, const Pose& X_WorldWrist,
                        const JointBends& bend) {
  HandPoints out;
  out.wrist = X_WorldWrist.p_m;
  for (int i = 0; i < 5; ++i) {
    const FingerGeometry& g = hand.fingers[static_cast<std::size_t>(i)];
    const glm::dvec3 dir0 = glm::normalize(mirror(g.dir_hand, hand.left));
    glm::dvec3 axis = glm::cross(dir0, mirror(g.curl_toward_hand, hand.left));
    // A curl direction parallel to the finger leaves no bending plane: keep the finger straight.
    const double axis_len = glm::length(axis);
    axis = axis_len > 1e-9 ? axis / axis_len : glm::dvec3{0.0};
    glm::dvec3 p = mirror(g.base_hand_m, hand.left);
    glm::dvec3 dir = dir0;
    double angle = 0.0;
    out.joints[static_cast<std::size_t>(i)][0] = X_WorldWrist.p_m + X_WorldWrist.q * p;
    for (int s = 0; s < 3; ++s) {
      const double raw = bend[static_cast<std::size_t>(i)][static_cast<std::size_t>(s)];
      const double b = std::isnan(raw) ? 0.0 : std::clamp(raw, 0.0, 1.0);
      angle += b * g.max_angle_rad[static_cast<std::size_t>(s)];
      dir = axis_len > 1e-9 ? glm::angleAxis(angle, axis) * dir0 : dir0;
      p += dir * g.segment_m[static_cast<std::size_t>(s)];
      out.joints[static_cast<std::size_t>(i)][static_cast<std::size_t>(s) + 1] =
          X_WorldWrist.p_m + X_WorldWrist.q * p;
    }
    out.axis[static_cast<std::size_t>(i)] = glm::normalize(X_WorldWrist.q * dir);
  }
  return out;
}

}  // namespace telex
