// SPDX-License-Identifier: MIT
// Registration of a depth map to another camera (the right eye): shift+scale, or full reprojection.
#pragma once

#include <cstddef>
#include <glm/mat3x3.hpp>
#include <glm/vec3.hpp>

#include "telex/common/depth_image.h"

namespace telex {

// Image-space registration: a depth pixel centre (u, v) lands at
//   u' = (u - depth.cx) * scale_x + target.cx + shift_x_px
//   v' = (v - depth.cy) * scale_y + target.cy + shift_y_px
// and its value gains depth_offset_mm. Exact only for surfaces at the nominal depth the shift was
// derived for: a point at depth Z is misplaced by fx_target * t_x * (1/Z - 1/Z_nominal) pixels.
struct ShiftScale {
  double shift_x_px = 0.0;
  double shift_y_px = 0.0;
  double scale_x = 1.0;  // field-of-view ratio: target focal length / depth focal length
  double scale_y = 1.0;
  int depth_offset_mm = 0;
};

// The shift+scale that is exact at `nominal_depth_m` for a target camera whose frame is the depth
// camera's translated (p_target = p_depth + t_target_from_depth_m), e.g. t = (-baseline, 0, 0)
// for a target camera `baseline` to the right. Throws std::invalid_argument on nominal <= 0.
ShiftScale shift_scale_from_calibration(const Intrinsics& depth, const Intrinsics& target,
                                        const glm::dvec3& t_target_from_depth_m,
                                        double nominal_depth_m);

// Resamples `depth` into the target image (target.width x target.height): every depth pixel
// covers the target pixels whose centres fall inside its mapped footprint, so no cracks open when
// scaling up, or the single pixel nearest its mapped centre when the footprint holds none (scaling
// down); where pixels collide the nearest depth wins; holes write nothing and stay holes.
DepthImage register_shift_scale(const DepthImage& depth, const ShiftScale& params,
                                const Intrinsics& target);

// p_target = rotation * p_depth + translation_m.
struct RigidTransform {
  glm::dmat3 rotation{1.0};
  glm::dvec3 translation_m{0.0};
};

// Full reprojection: back-projects every valid depth pixel with the depth intrinsics, transforms
// it into the target frame, projects it with the target intrinsics to the nearest pixel and keeps
// the nearest depth there (z-buffer). With fill_cracks, pixels still empty afterwards take the
// nearest of the points whose 2x2 splat (the four pixels around the projected position) covers
// them, which closes the one-pixel cracks that magnification and parallax leave.
DepthImage reproject_depth(const DepthImage& depth, const Intrinsics& target,
                           const RigidTransform& target_from_depth, bool fill_cracks = true);

// reproject_depth for the one case a stereo view draws every frame: the target camera has the
// depth's intrinsics and sits `shift_m` along its x axis (p_target = p_depth + (shift_m, 0, 0);
// the left eye seeing the right eye's depth: +baseline). A point then stays on its row and moves
// fx shift_m / z pixels along it, so the rows are done apart, without a rotation per pixel or a
// frame-sized splat buffer: the nearest depth wins each pixel, and a pixel no point lands on
// takes the nearest of the points whose two-pixel splat along the row covers it (the cracks a
// slanted surface opens). Writes into `out` (reallocated only when its size differs). A depth of
// 65535 mm reads as none. Throws std::invalid_argument when fx is not > 0.
void shift_depth_along_rows(const cv::Mat1w& depth_mm, double fx, double shift_m, cv::Mat1w& out);

// Closes, in a depth image reprojected to a camera displaced sideways by `baseline_m` (the left
// eye seeing the right eye's depth), the gaps the displacement opens: along each row, a run of
// holes between a nearer and a farther depth takes the farther (what was uncovered lies behind
// the occluder), and a run at the image's side takes its one neighbour's depth. Only runs no
// wider than the parallax could open are closed, fx |baseline| (1/z_near - 1/z_far) at an edge and
// fx |baseline| / z at the side, plus `slack_px`: a wider hole is the sensor's and stays a hole.
// Returns the pixels filled. Throws std::invalid_argument when fx is not > 0.
std::size_t fill_disocclusions(cv::Mat1w& depth_mm, double fx, double baseline_m,
                               double slack_px = 2.0);

}  // namespace telex
