// SPDX-License-Identifier: MIT
// The body's plain dimensions: the default hand and the rig's check of a body.
#include "telex/common/body_dims.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace telex {
namespace {

bool finite(const glm::dvec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

void require(bool ok, const char* field, const char* what) {
  if (!ok) throw std::invalid_argument(std::string("body: ") + field + " " + what);
}

}  // namespace

std::array<FingerGeometry, 5> HandGeometry::default_fingers() {
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

void BodyDims::validate() const {
  const auto length = [](double v) { return std::isfinite(v) && v > 0.0 && v < 5.0; };
  require(length(upper_arm_m), "upper_arm_m", "must be a length in (0, 5) m");
  require(length(forearm_m), "forearm_m", "must be a length in (0, 5) m");
  require(finite(p_HeadEyes), "p_HeadEyes", "must be finite");
  require(std::isfinite(ipd_m) && ipd_m >= 0.0 && ipd_m < 0.2, "ipd_m", "must be in [0, 0.2) m");
  require(finite(forearm_axis_wrist) && glm::length(forearm_axis_wrist) > 1e-9,
          "forearm_axis_wrist", "must be a finite non-zero direction");
  require(finite(up_world) && glm::length(up_world) > 1e-9, "up_world",
          "must be a finite non-zero direction");
  require(std::isfinite(elbow_out_weight) && elbow_out_weight >= 0.0, "elbow_out_weight",
          "must be finite and not negative");
  require(std::isfinite(elbow_back_weight) && elbow_back_weight >= 0.0, "elbow_back_weight",
          "must be finite and not negative");
  require(std::isfinite(hold_s) && hold_s >= 0.0, "hold_s", "must be finite and not negative");
  require(std::isfinite(swivel_rate_rad_s) && swivel_rate_rad_s > 0.0, "swivel_rate_rad_s",
          "must be finite and positive");
}

}  // namespace telex
