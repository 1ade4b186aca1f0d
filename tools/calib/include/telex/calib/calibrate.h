// SPDX-License-Identifier: MIT
// Camera calibration from chessboard corners (OpenCV calib3d): each eye's intrinsics, the stereo
// extrinsics, and the depth sensor's pose relative to the right eye. Pure functions over corner
// lists and depth images; no files (the `telex calibrate` command reads and writes those).
#pragma once

#include <opencv2/core.hpp>
#include <optional>
#include <stdexcept>
#include <vector>

#include "telex/calib/board.h"
#include "telex/common/depth_image.h"
#include "telex/common/registration.h"
#include "telex/common/rig.h"

namespace telex::calib {

// The calibration could not be made from these views (too few, degenerate): the command's exit 1.
class CalibrationError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Corners of one camera's views, each in board_points order.
using ViewCorners = std::vector<std::vector<cv::Point2f>>;

struct CalibrateOptions {
  int min_views = 5;
  bool fix_k3 = true;  // the k3 term only for wide-angle lenses: it over-fits ordinary ones
  // Stereo: refine both eyes' intrinsics together with the extrinsics (the board poses shared by
  // the two eyes constrain each eye's focal length) instead of holding each eye's own.
  bool joint_refine = true;
};

struct CameraCalibration {
  CameraModel model;
  double rms_px = 0.0;                        // over all corners of all views
  std::vector<double> view_rms_px;            // per view
  std::vector<RigidTransform> X_CameraBoard;  // per view
};

// One camera's intrinsics and distortion (calibrateCamera). Throws CalibrationError with fewer
// than options.min_views views or when OpenCV's solve fails; std::invalid_argument when a view's
// corner count is not the board's.
CameraCalibration calibrate_camera(const ViewCorners& views, const BoardSpec& board,
                                   cv::Size image_size, const CalibrateOptions& options = {});

struct StereoCalibration {
  CameraCalibration left, right;
  // p_right = rotation * p_left + translation_m: for a left eye one baseline to the left of the
  // right eye, translation_m ~ (-baseline, 0, 0).
  RigidTransform X_RightEyeLeftEye;
  double rms_px = 0.0;  // stereoCalibrate's, over both cameras' corners
  std::vector<double> view_rms_px;
  double baseline_m() const;
};

// Each eye's intrinsics, then the extrinsics with the intrinsics held (stereoCalibrate with
// CALIB_FIX_INTRINSIC). `left[i]` and `right[i]` are the same moment. Throws as calibrate_camera.
StereoCalibration calibrate_stereo(const ViewCorners& left, const ViewCorners& right,
                                   const BoardSpec& board, cv::Size left_size, cv::Size right_size,
                                   const CalibrateOptions& options = {});

// The rigid transform X (p_b = X.rotation * p_a + X.translation_m) minimising the summed squared
// distance between X * a[i] and b[i] (Kabsch / Umeyama without scale, SVD). Throws
// std::invalid_argument on fewer than 3 points, differing counts, or collinear points.
RigidTransform fit_rigid_transform(const std::vector<cv::Point3d>& a,
                                   const std::vector<cv::Point3d>& b);

// Rotation vector (axis * angle, radians) of a rotation matrix, and the angle of R_a^T R_b.
cv::Vec3d rotation_vector_rad(const glm::dmat3& rotation);
double rotation_angle_between_rad(const glm::dmat3& a, const glm::dmat3& b);
RigidTransform compose(const RigidTransform& X_AB, const RigidTransform& X_BC);
RigidTransform inverse(const RigidTransform& X_AB);
glm::dvec3 apply(const RigidTransform& X_AB, const glm::dvec3& p_B);

// The board plane seen in a depth map (with its IR image's corners marking where the board is).
struct DepthPlaneView {
  bool used = false;
  glm::dvec3 normal_Depth{0.0};  // unit, pointing away from the sensor (the board's +z)
  double offset_m = 0.0;         // normal . p = offset_m for points p on the plane
  int points = 0;
  double fit_rms_mm = 0.0;             // depth points about their fitted plane
  double offset_to_ir_plane_mm = 0.0;  // depth plane minus IR PnP plane along the normal, at
                                       // the board's centre (depth bias or IR/depth misalignment)
  double angle_to_ir_plane_deg = 0.0;
};

struct DepthEyeCalibration {
  // p_right = rotation * p_depth + translation_m. From the IR and eye corners: a joint fit of all
  // corners placed by per-view PnP (fit_rigid_transform), refined by stereoCalibrate on the
  // reprojection errors in both images with both cameras' intrinsics held.
  RigidTransform X_RightEyeDepth;
  // The board's corners placed by the depth sensor's PnP pose carried through X_RightEyeDepth,
  // against the same corners placed by the eye's PnP pose: RMS distance, millimetres.
  double residual_mm = 0.0;
  double rms_px = 0.0;  // reprojection RMS of the refinement (both images)
  std::vector<double> view_residual_mm;
  std::vector<RigidTransform> X_DepthBoard, X_RightEyeBoard;  // per view, PnP
  // With depth maps: the board plane in each depth map against the IR PnP plane, and the second,
  // independent estimate from planes alone (rotation from matched normals, translation from the
  // planes' offsets), which uses the depth values instead of the IR image's geometry.
  std::vector<DepthPlaneView> planes;
  std::optional<RigidTransform> X_RightEyeDepth_from_planes;
};

// The depth sensor's pose relative to the right eye from views of the board seen at the same
// moment by the depth sensor's IR camera (the depth intrinsics, no distortion: the depth image
// lives in the IR camera's pixels) and by the right eye (its calibrated model). `depth_maps`, when
// not empty, holds one depth map per view (CV_16UC1, mm, 0 = hole) for the plane figures. Throws
// CalibrationError with fewer than options.min_views views, std::invalid_argument on mismatched
// inputs.
DepthEyeCalibration calibrate_depth_eye(const ViewCorners& ir, const ViewCorners& right,
                                        const BoardSpec& board, const Intrinsics& depth,
                                        const CameraModel& right_eye,
                                        const std::vector<cv::Mat1w>& depth_maps = {},
                                        const CalibrateOptions& options = {});

// The least-squares plane of the depth pixels inside the polygon of the board's outermost inner
// corners (a square inside the board's edge, so the depth edge's smear stays out), back-projected
// with `depth`, refitted once without points more than 3 RMS off. nullopt with fewer than 50
// valid pixels.
std::optional<DepthPlaneView> fit_board_plane(const cv::Mat1w& depth_mm, const Intrinsics& depth,
                                              const std::vector<cv::Point2f>& ir_corners_px,
                                              const BoardSpec& board);

// Conversions between OpenCV's and the rig's types.
cv::Matx33d camera_matrix(const Intrinsics& k);
cv::Mat distortion_mat(const CameraModel& m);
RigidTransform transform_from_cv(const cv::Mat& R, const cv::Mat& t);

}  // namespace telex::calib
