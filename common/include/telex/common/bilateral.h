// SPDX-License-Identifier: MIT
// Edge-preserving bilateral filter for depth maps that ignores holes; output in float metres.
#pragma once

#include <opencv2/core.hpp>

namespace telex {

struct BilateralOptions {
  // Window radius: taps at Euclidean distance <= radius_px, the disc cv::bilateralFilter uses for
  // d = 2 * radius_px + 1. The KinectFusion setting is radius 6 (13x13), sigma 4.5 px, 30 mm.
  int radius_px = 2;
  double sigma_space_px = 4.5;
  double sigma_depth_mm = 30.0;
  // When true the depth sigma of each pixel is noise_sigma_factor * the Nguyen axial noise at its
  // depth, sigma_z = 0.0012 + 0.0019 (z - 0.4)^2 m, instead of sigma_depth_mm.
  bool sigma_from_noise_model = false;
  double noise_sigma_factor = 3.0;
  // Use the AVX2 kernel when the CPU has it (the scalar kernel gives the same result to ~1e-6
  // relative; tests compare both).
  bool allow_simd = true;
};

// Filters `depth_mm` (CV_16UC1, 0 = hole) into `depth_m_out` (CV_32FC1, metres, 0 = hole; sized
// like the input, reallocated only when its size differs). Holes neither contribute nor get
// written (they stay 0); neighbours more than 3 depth sigmas from the centre are ignored.
// Throws std::invalid_argument on bad options or an empty image.
void bilateral_filter_depth(const cv::Mat1w& depth_mm, cv::Mat1f& depth_m_out,
                            const BilateralOptions& options = {});
cv::Mat1f bilateral_filter_depth(const cv::Mat1w& depth_mm, const BilateralOptions& options = {});

// Filters only the pixels of `roi` (neighbours outside it are read), so the result equals the
// full-frame result inside the ROI. `depth_m_out` gets roi.size().
void bilateral_filter_depth_roi(const cv::Mat1w& depth_mm, const cv::Rect& roi,
                                cv::Mat1f& depth_m_out, const BilateralOptions& options = {});

// Nguyen, Izadi, Lovell 2012 axial noise for 10-60 degree incidence, metres.
inline double nguyen_axial_sigma_m(double z_m) {
  return 0.0012 + 0.0019 * (z_m - 0.4) * (z_m - 0.4);
}

}  // namespace telex
