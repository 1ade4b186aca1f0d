// SPDX-License-Identifier: MIT
// Depth image type: 16-bit millimetres (0 = no data) with the pinhole intrinsics it was taken with.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>

namespace telex {

// Pinhole intrinsics in pixels. width/height describe the image the intrinsics belong to.
struct Intrinsics {
  double fx = 525.0;
  double fy = 525.0;
  double cx = 319.5;
  double cy = 239.5;
  int width = 640;
  int height = 480;

  // Intrinsics of the same camera at another resolution (principal point and focal scale).
  Intrinsics scaled(int new_width, int new_height) const;
  bool operator==(const Intrinsics&) const = default;
};

// Kinect v1 intrinsics at 640x480 scaled to the requested size.
Intrinsics kinect_v1_intrinsics(int width = 640, int height = 480);

inline constexpr std::uint16_t kNoDepth = 0;

// A depth frame in millimetres. `depth_mm` is CV_16UC1; 0 marks a hole.
struct DepthImage {
  cv::Mat1w depth_mm;
  Intrinsics intrinsics;

  int width() const { return depth_mm.cols; }
  int height() const { return depth_mm.rows; }
  bool empty() const { return depth_mm.empty(); }
};

// Count of hole pixels (value 0).
std::size_t count_holes(const cv::Mat1w& depth_mm);

// Millimetre depth image (0 = hole) to metres (0 = hole).
cv::Mat1f depth_m_from_mm(const cv::Mat1w& depth_mm);

}  // namespace telex
