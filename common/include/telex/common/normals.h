// SPDX-License-Identifier: MIT
// Surface normal maps from depth: cross product of smoothed depth derivatives in camera space.
#pragma once

#include <opencv2/core.hpp>

#include "telex/common/depth_image.h"

namespace telex {

struct NormalOptions {
  // Half-width k of the box that averages the central differences: the derivative along x is the
  // mean of the central differences over a (2k+1)x(2k+1) box, which telescopes to four columns of
  // a (2k+3)x(2k+1) stencil. k = 2 beats a 5x5 least-squares plane (OpenCV FALS) on noise; k = 0 is
  // plain central differences. Where the wide stencil meets a hole or a discontinuity the kernel
  // falls back to central differences, then one-sided ones.
  int smooth_radius_px = 2;
  // Neighbouring pixels whose depths differ by more than this fraction of the nearer depth lie on
  // different surfaces: no derivative is taken across them.
  double discontinuity_ratio = 0.03;
  // Use the AVX2 row passes when the CPU has them (bit-identical to the scalar passes).
  bool allow_simd = true;
};

// Millimetre images convert with depth_m_from_mm (depth_image.h).
// Unit normals (x, y, z in the camera frame: x right, y down, z forward) facing the camera (n.z < 0
// for a surface seen head-on). Invalid normals are the zero vector (0, 0, 0): at holes (0 or NaN
// depth) and where no derivative exists on one side of a discontinuity in either direction.
// `normals_out` gets depth_m.size(). Throws std::invalid_argument on bad options or input.
void compute_normals(const cv::Mat1f& depth_m, const Intrinsics& intrinsics, cv::Mat3f& normals_out,
                     const NormalOptions& options = {});
cv::Mat3f compute_normals(const cv::Mat1f& depth_m, const Intrinsics& intrinsics,
                          const NormalOptions& options = {});

// Normals of the pixels of `roi` only, reading neighbours outside it: equal to the full-frame
// result inside the ROI. `normals_out` gets roi.size().
void compute_normals_roi(const cv::Mat1f& depth_m, const Intrinsics& intrinsics,
                         const cv::Rect& roi, cv::Mat3f& normals_out,
                         const NormalOptions& options = {});

// A colour view of normals: colorize_normals() in colorize.h.

}  // namespace telex
