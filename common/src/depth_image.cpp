// SPDX-License-Identifier: MIT
// Depth image type helpers.
#include "telex/common/depth_image.h"

namespace telex {

Intrinsics Intrinsics::scaled(int new_width, int new_height) const {
  Intrinsics out = *this;
  const double sx = static_cast<double>(new_width) / width;
  const double sy = static_cast<double>(new_height) / height;
  out.fx = fx * sx;
  out.fy = fy * sy;
  // Pixel centres: a principal point at c maps to (c + 0.5) * s - 0.5.
  out.cx = (cx + 0.5) * sx - 0.5;
  out.cy = (cy + 0.5) * sy - 0.5;
  out.width = new_width;
  out.height = new_height;
  return out;
}

Intrinsics kinect_v1_intrinsics(int width, int height) {
  Intrinsics k{525.0, 525.0, 319.5, 239.5, 640, 480};
  if (width == 640 && height == 480) return k;
  return k.scaled(width, height);
}

std::size_t count_holes(const cv::Mat1w& depth_mm) {
  return depth_mm.total() - static_cast<std::size_t>(cv::countNonZero(depth_mm));
}

cv::Mat1f depth_m_from_mm(const cv::Mat1w& depth_mm) {
  cv::Mat1f out;
  depth_mm.convertTo(out, CV_32F, 1e-3);
  return out;
}

}  // namespace telex
