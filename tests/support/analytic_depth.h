// SPDX-License-Identifier: MIT
// Analytic depth images for the view's tests: surfaces whose normals are known exactly.
#pragma once

#include <cmath>
#include <cstdint>
#include <glm/glm.hpp>
#include <opencv2/core.hpp>

#include "telex/common/depth_image.h"

namespace telex::test {

// A wall 80 cm away facing the camera on the left half of the image, and on the right half a
// plane of normal n_right (camera frame) continuing the wall at the image's centre column.
inline cv::Mat1w two_planes(const Intrinsics& k, const glm::dvec3& n_right) {
  cv::Mat1w d(k.height, k.width);
  for (int v = 0; v < k.height; ++v)
    for (int u = 0; u < k.width; ++u) {
      const glm::dvec3 ray{(u - k.cx) / k.fx, (v - k.cy) / k.fy, 1.0};
      const double z = u < k.cx ? 0.8 : n_right.z * 0.8 / glm::dot(n_right, ray);
      d(v, u) = static_cast<std::uint16_t>(std::lround(z * 1000.0));
    }
  return d;
}

}  // namespace telex::test
