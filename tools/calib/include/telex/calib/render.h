// SPDX-License-Identifier: MIT
// Renders calibration boards with known answers (board poses, intrinsics, distortion, extrinsics)
// for the calibration tests and `telex calibrate render`: inverse mapping per pixel (undistort ->
// ray -> board plane -> square colour) with supersampling, then Gaussian blur and noise, all from
// fixed seeds.
#pragma once

#include <array>
#include <cstdint>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "telex/calib/board.h"
#include "telex/common/registration.h"
#include "telex/common/rig.h"

namespace telex::calib {

struct RenderStyle {
  int supersample = 3;         // samples per pixel side (anti-aliasing)
  double blur_sigma_px = 0.8;  // Gaussian, after sampling (lens and sensor blur)
  double noise_sigma = 2.0;    // grey levels, Gaussian, added last
  double black = 30.0, white = 220.0, background = 110.0;  // grey levels
  double margin_squares = 0.75;  // white border around the squares, in squares
};

// The IR image of a structured-light sensor with its projector covered: darker, noisier.
RenderStyle ir_style();

// One camera with lens distortion, its undistorted ray per sub-sample computed once.
class BoardRenderer {
 public:
  // Throws std::invalid_argument on a bad model (size, focal length) or style.
  BoardRenderer(const CameraModel& camera, const BoardSpec& board, const RenderStyle& style);

  // The board at X_CameraBoard as an 8-bit grey image of the camera's size; `seed` drives the
  // noise.
  cv::Mat render(const RigidTransform& X_CameraBoard, std::uint64_t seed) const;
  // Depth in mm (CV_16UC1) at each pixel centre: the board and its border, a wall parallel to the
  // image plane at `wall_m` behind everything else (0 = no wall: holes), with Gaussian noise of
  // `noise_mm` (fixed seed), rounded to whole millimetres.
  cv::Mat1w render_depth(const RigidTransform& X_CameraBoard, double wall_m, double noise_mm,
                         std::uint64_t seed) const;

  // Where the camera's model puts a point of its frame (distortion applied), pixels.
  cv::Point2d project(const glm::dvec3& p_Camera) const;
  const CameraModel& camera() const { return camera_; }

 private:
  CameraModel camera_;
  BoardSpec board_;
  RenderStyle style_;
  std::vector<cv::Point2f> rays_;  // undistorted normalised (x, y) per sub-sample
};

// The undistorted normalised coordinates whose distorted projection is (xd, yd) (OpenCV's
// 5-coefficient model), by fixed-point iteration to 1e-12 from `start` (default: xd itself).
cv::Point2d undistort_normalised(const std::array<double, 5>& distortion, cv::Point2d xd,
                                 std::optional<cv::Point2d> start = std::nullopt);

// A rig of cameras looking at one board: each camera's pose in a common frame (X_CameraRig).
struct RenderCamera {
  CameraModel model;
  RigidTransform X_CameraRig;
};

// `count` board poses in the rig's frame, drawn with `seed`: 0.35-0.75 m in front of the rig's
// origin, tilted up to 40 degrees about x and y and turned up to 25 degrees in plane, each kept
// only when every corner (and the border) lands at least `margin_px` inside every camera's image
// and the printed face is towards every camera, at most 50 degrees off its normal. Throws
// std::runtime_error when the cameras share too little view to place `count` poses.
std::vector<RigidTransform> random_board_poses(const BoardSpec& board,
                                               const std::vector<RenderCamera>& cameras, int count,
                                               std::uint64_t seed, double margin_px = 12.0);

// The known answers of a rendered set: both eyes and the depth sensor's IR camera, in the rig
// file's conventions (X_RightEyeLeftEye: p_right = R p_left + t).
struct RenderRig {
  CameraModel left, right;
  CameraModel depth;  // the IR camera, no distortion (the rig's `depth` key holds none)
  RigidTransform X_RightEyeLeftEye, X_RightEyeDepth;
};

// A head like the paper's: two 640x480 eyes 65 mm apart with barrel distortion, slightly turned
// against each other, and a Carmine-like depth sensor (f 570.3 px) 32.5 mm left of and 45 mm
// below the right eye, turned by about a degree.
RenderRig example_render_rig();

struct RenderedView {
  RigidTransform X_RightEyeBoard;
  cv::Mat left, right, ir;  // 8-bit grey
  cv::Mat1w depth_mm;       // the depth sensor's depth map of the board (a wall at 1.6 m behind)
};

// `count` views of the board placed by random_board_poses(seed) in view of all three cameras,
// each camera's image from its own fixed noise seed. The IR image uses ir_style(); the depth map
// has `depth_noise_mm` Gaussian noise.
std::vector<RenderedView> render_views(const RenderRig& rig, const BoardSpec& board, int count,
                                       std::uint64_t seed, const RenderStyle& eye_style = {},
                                       double depth_noise_mm = 1.0);

}  // namespace telex::calib
