// SPDX-License-Identifier: MIT
// Intrinsics, stereo extrinsics and the depth-to-eye pose from chessboard corners (OpenCV calib3d).
#include "telex/calib/calibrate.h"

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <string>

namespace telex::calib {
namespace {

constexpr double kPi = 3.14159265358979323846;

glm::dmat3 to_glm(const cv::Matx33d& m) {
  glm::dmat3 r;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) r[j][i] = m(i, j);  // glm is column-major
  return r;
}

cv::Matx33d to_cv(const glm::dmat3& r) {
  cv::Matx33d m;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) m(i, j) = r[j][i];
  return m;
}

glm::dvec3 to_glm(const cv::Point3f& p) { return {p.x, p.y, p.z}; }

void check_views(const ViewCorners& views, const BoardSpec& board, const char* what) {
  for (std::size_t i = 0; i < views.size(); ++i)
    if (static_cast<int>(views[i].size()) != board.corner_count())
      throw std::invalid_argument(std::string(what) + " view " + std::to_string(i) + " has " +
                                  std::to_string(views[i].size()) + " corners, the board " +
                                  std::to_string(board.corner_count()));
}

void check_count(std::size_t views, const CalibrateOptions& options, const char* what) {
  if (static_cast<int>(views) < options.min_views)
    throw CalibrationError(std::string(what) + ": " + std::to_string(views) +
                           " views show the board, at least " + std::to_string(options.min_views) +
                           " are needed");
}

bool finite(const cv::Mat& m) { return cv::checkRange(m); }

RigidTransform pose_from_rt(const cv::Mat& rvec, const cv::Mat& tvec) {
  cv::Matx33d R;
  cv::Rodrigues(rvec, R);
  RigidTransform x;
  x.rotation = to_glm(R);
  x.translation_m = {tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2)};
  return x;
}

// The camera's pose of the board from its corners: IPPE for a planar target, then refined by
// Levenberg-Marquardt on the reprojection error.
RigidTransform solve_pose(const std::vector<cv::Point3f>& object,
                          const std::vector<cv::Point2f>& px, const cv::Matx33d& K,
                          const cv::Mat& D) {
  cv::Mat rvec, tvec;
  if (!cv::solvePnP(object, px, K, D, rvec, tvec, false, cv::SOLVEPNP_IPPE))
    throw CalibrationError("solvePnP found no pose of the board");
  cv::solvePnPRefineLM(object, px, K, D, rvec, tvec);
  return pose_from_rt(rvec, tvec);
}

void set_model(CameraModel& m, const cv::Mat& K, const cv::Mat& D) {
  m.k.fx = K.at<double>(0, 0);
  m.k.fy = K.at<double>(1, 1);
  m.k.cx = K.at<double>(0, 2);
  m.k.cy = K.at<double>(1, 2);
  for (int i = 0; i < 5; ++i) m.distortion[static_cast<std::size_t>(i)] = D.at<double>(i);
}

std::vector<std::vector<cv::Point3f>> repeat(const std::vector<cv::Point3f>& p, std::size_t n) {
  return std::vector<std::vector<cv::Point3f>>(n, p);
}

}  // namespace

cv::Matx33d camera_matrix(const Intrinsics& k) {
  return {k.fx, 0.0, k.cx, 0.0, k.fy, k.cy, 0.0, 0.0, 1.0};
}

cv::Mat distortion_mat(const CameraModel& m) {
  cv::Mat d(1, 5, CV_64F);
  for (int i = 0; i < 5; ++i) d.at<double>(i) = m.distortion[static_cast<std::size_t>(i)];
  return d;
}

RigidTransform transform_from_cv(const cv::Mat& R, const cv::Mat& t) {
  cv::Mat r, tt;
  R.convertTo(r, CV_64F);
  t.convertTo(tt, CV_64F);
  RigidTransform x;
  x.rotation = to_glm(cv::Matx33d(r));
  x.translation_m = {tt.at<double>(0), tt.at<double>(1), tt.at<double>(2)};
  return x;
}

RigidTransform compose(const RigidTransform& X_AB, const RigidTransform& X_BC) {
  return {X_AB.rotation * X_BC.rotation, X_AB.rotation * X_BC.translation_m + X_AB.translation_m};
}

RigidTransform inverse(const RigidTransform& X_AB) {
  const glm::dmat3 Rt = glm::transpose(X_AB.rotation);
  return {Rt, -(Rt * X_AB.translation_m)};
}

glm::dvec3 apply(const RigidTransform& X_AB, const glm::dvec3& p_B) {
  return X_AB.rotation * p_B + X_AB.translation_m;
}

cv::Vec3d rotation_vector_rad(const glm::dmat3& rotation) {
  cv::Vec3d r;
  cv::Rodrigues(to_cv(rotation), r);
  return r;
}

double rotation_angle_between_rad(const glm::dmat3& a, const glm::dmat3& b) {
  const glm::dmat3 d = glm::transpose(a) * b;
  const double c = std::clamp((d[0][0] + d[1][1] + d[2][2] - 1.0) * 0.5, -1.0, 1.0);
  // acos loses precision near 0; the rotation vector's norm does not.
  if (c > 0.99) return cv::norm(rotation_vector_rad(d));
  return std::acos(c);
}

double StereoCalibration::baseline_m() const {
  return glm::length(X_RightEyeLeftEye.translation_m);
}

CameraCalibration calibrate_camera(const ViewCorners& views, const BoardSpec& board,
                                   cv::Size image_size, const CalibrateOptions& options) {
  check_views(views, board, "camera");
  check_count(views.size(), options, "camera calibration");
  if (image_size.width <= 0 || image_size.height <= 0)
    throw std::invalid_argument("calibrate_camera: empty image size");
  const auto object = repeat(board_points(board), views.size());
  cv::Mat K = cv::Mat::eye(3, 3, CV_64F), D = cv::Mat::zeros(1, 5, CV_64F);
  std::vector<cv::Mat> rvecs, tvecs;
  cv::Mat std_intrinsics, std_extrinsics, per_view;
  const int flags = options.fix_k3 ? cv::CALIB_FIX_K3 : 0;
  double rms = 0.0;
  try {
    rms = cv::calibrateCamera(
        object, views, image_size, K, D, rvecs, tvecs, std_intrinsics, std_extrinsics, per_view,
        flags, cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 100, DBL_EPSILON));
  } catch (const cv::Exception& e) {
    throw CalibrationError(std::string("calibrateCamera failed: ") + e.what());
  }
  if (!std::isfinite(rms) || !finite(K) || !finite(D) || K.at<double>(0, 0) <= 0.0 ||
      K.at<double>(1, 1) <= 0.0)
    throw CalibrationError("calibrateCamera gave no usable intrinsics (views too alike?)");
  CameraCalibration c;
  c.model.k.width = image_size.width;
  c.model.k.height = image_size.height;
  set_model(c.model, K, D);
  c.rms_px = rms;
  for (int i = 0; i < per_view.rows; ++i) c.view_rms_px.push_back(per_view.at<double>(i));
  for (std::size_t i = 0; i < rvecs.size(); ++i)
    c.X_CameraBoard.push_back(pose_from_rt(rvecs[i], tvecs[i]));
  return c;
}

StereoCalibration calibrate_stereo(const ViewCorners& left, const ViewCorners& right,
                                   const BoardSpec& board, cv::Size left_size, cv::Size right_size,
                                   const CalibrateOptions& options) {
  if (left.size() != right.size())
    throw std::invalid_argument("calibrate_stereo: " + std::to_string(left.size()) +
                                " left views but " + std::to_string(right.size()) + " right");
  check_views(left, board, "left");
  check_views(right, board, "right");
  check_count(left.size(), options, "stereo calibration");
  StereoCalibration s;
  s.left = calibrate_camera(left, board, left_size, options);
  s.right = calibrate_camera(right, board, right_size, options);
  cv::Mat K1(camera_matrix(s.left.model.k)), D1 = distortion_mat(s.left.model);
  cv::Mat K2(camera_matrix(s.right.model.k)), D2 = distortion_mat(s.right.model);
  cv::Mat R, T, E, F, per_view;
  try {
    s.rms_px = cv::stereoCalibrate(
        repeat(board_points(board), left.size()), left, right, K1, D1, K2, D2, left_size, R, T, E,
        F, per_view,
        options.joint_refine
            ? cv::CALIB_USE_INTRINSIC_GUESS | (options.fix_k3 ? cv::CALIB_FIX_K3 : 0)
            : cv::CALIB_FIX_INTRINSIC,
        cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 100, 1e-12));
  } catch (const cv::Exception& e) {
    throw CalibrationError(std::string("stereoCalibrate failed: ") + e.what());
  }
  if (!std::isfinite(s.rms_px) || !finite(R) || !finite(T))
    throw CalibrationError("stereoCalibrate gave no usable extrinsics");
  s.X_RightEyeLeftEye = transform_from_cv(R, T);
  if (options.joint_refine) {
    if (!finite(K1) || !finite(K2) || !finite(D1) || !finite(D2))
      throw CalibrationError("stereoCalibrate's joint refinement gave no usable intrinsics");
    set_model(s.left.model, K1, D1);
    set_model(s.right.model, K2, D2);
  }
  for (int i = 0; i < per_view.rows; ++i) {
    const double a = per_view.at<double>(i, 0), b = per_view.at<double>(i, 1);
    s.view_rms_px.push_back(std::sqrt(0.5 * (a * a + b * b)));
  }
  if (s.baseline_m() < 1e-3)
    throw CalibrationError(
        "stereo calibration put the eyes less than 1 mm apart (the same images "
        "for both eyes?)");
  return s;
}

RigidTransform fit_rigid_transform(const std::vector<cv::Point3d>& a,
                                   const std::vector<cv::Point3d>& b) {
  if (a.size() != b.size())
    throw std::invalid_argument("fit_rigid_transform: " + std::to_string(a.size()) + " vs " +
                                std::to_string(b.size()) + " points");
  if (a.size() < 3) throw std::invalid_argument("fit_rigid_transform: needs at least 3 points");
  cv::Vec3d ca(0, 0, 0), cb(0, 0, 0);
  for (std::size_t i = 0; i < a.size(); ++i) {
    ca += cv::Vec3d(a[i]);
    cb += cv::Vec3d(b[i]);
  }
  ca /= static_cast<double>(a.size());
  cb /= static_cast<double>(b.size());
  cv::Matx33d H = cv::Matx33d::zeros(), Saa = cv::Matx33d::zeros();
  for (std::size_t i = 0; i < a.size(); ++i) {
    const cv::Vec3d da = cv::Vec3d(a[i]) - ca, db = cv::Vec3d(b[i]) - cb;
    H += da * db.t();
    Saa += da * da.t();
  }
  cv::Vec3d spread;
  cv::SVD::compute(Saa, spread, cv::SVD::NO_UV);
  if (!(spread[1] > 1e-12 * std::max(1.0, spread[0])))
    throw std::invalid_argument("fit_rigid_transform: the points are collinear");
  cv::Matx33d U, Vt;
  cv::Vec3d w;
  cv::SVD::compute(H, w, U, Vt);
  // H = U W Vt; R = V diag(1, 1, det(V U^T)) U^T maps a's spread onto b's.
  const cv::Matx33d V = Vt.t();
  const double det = cv::determinant(V * U.t());
  const cv::Matx33d Dg(1, 0, 0, 0, 1, 0, 0, 0, det < 0 ? -1.0 : 1.0);
  const cv::Matx33d R = V * Dg * U.t();
  const cv::Vec3d t = cb - R * ca;
  return {to_glm(R), {t[0], t[1], t[2]}};
}

std::optional<DepthPlaneView> fit_board_plane(const cv::Mat1w& depth_mm, const Intrinsics& depth,
                                              const std::vector<cv::Point2f>& ir_corners_px,
                                              const BoardSpec& board) {
  if (static_cast<int>(ir_corners_px.size()) != board.corner_count() || depth_mm.empty())
    return std::nullopt;
  const int C = board.cols, R = board.rows;
  const std::vector<cv::Point> polygon{ir_corners_px[0],
                                       ir_corners_px[static_cast<std::size_t>(C - 1)],
                                       ir_corners_px[static_cast<std::size_t>(R * C - 1)],
                                       ir_corners_px[static_cast<std::size_t>((R - 1) * C)]};
  cv::Mat1b mask = cv::Mat1b::zeros(depth_mm.size());
  cv::fillConvexPoly(mask, polygon, cv::Scalar(255));
  std::vector<cv::Vec3d> pts;
  for (int v = 0; v < depth_mm.rows; ++v)
    for (int u = 0; u < depth_mm.cols; ++u) {
      const std::uint16_t z = depth_mm(v, u);
      if (!mask(v, u) || z == kNoDepth) continue;
      const double Z = z * 1e-3;
      pts.emplace_back((u - depth.cx) * Z / depth.fx, (v - depth.cy) * Z / depth.fy, Z);
    }
  DepthPlaneView plane;
  auto fit = [&](const std::vector<cv::Vec3d>& p) {
    cv::Vec3d c(0, 0, 0);
    for (const auto& q : p) c += q;
    c /= static_cast<double>(p.size());
    cv::Matx33d S = cv::Matx33d::zeros();
    for (const auto& q : p) S += (q - c) * (q - c).t();
    cv::Matx31d evals;
    cv::Matx33d evecs;
    cv::eigen(S, evals, evecs);  // descending: the last row is the normal
    cv::Vec3d n(evecs(2, 0), evecs(2, 1), evecs(2, 2));
    if (n[2] < 0) n = -n;
    plane.normal_Depth = {n[0], n[1], n[2]};
    plane.offset_m = n.dot(c);
    double ss = 0.0;
    for (const auto& q : p) ss += std::pow(n.dot(q) - plane.offset_m, 2);
    plane.points = static_cast<int>(p.size());
    plane.fit_rms_mm = std::sqrt(ss / static_cast<double>(p.size())) * 1e3;
  };
  if (pts.size() < 50) return std::nullopt;
  fit(pts);
  const glm::dvec3 n = plane.normal_Depth;
  const double limit_m = std::max(3.0 * plane.fit_rms_mm * 1e-3, 1e-4);
  std::vector<cv::Vec3d> kept;
  for (const auto& q : pts)
    if (std::abs(n.x * q[0] + n.y * q[1] + n.z * q[2] - plane.offset_m) <= limit_m)
      kept.push_back(q);
  if (kept.size() < 50) return std::nullopt;
  fit(kept);
  plane.used = true;
  return plane;
}

DepthEyeCalibration calibrate_depth_eye(const ViewCorners& ir, const ViewCorners& right,
                                        const BoardSpec& board, const Intrinsics& depth,
                                        const CameraModel& right_eye,
                                        const std::vector<cv::Mat1w>& depth_maps,
                                        const CalibrateOptions& options) {
  if (ir.size() != right.size())
    throw std::invalid_argument("calibrate_depth_eye: " + std::to_string(ir.size()) +
                                " IR views but " + std::to_string(right.size()) + " right");
  if (!depth_maps.empty() && depth_maps.size() != ir.size())
    throw std::invalid_argument("calibrate_depth_eye: " + std::to_string(depth_maps.size()) +
                                " depth maps for " + std::to_string(ir.size()) + " views");
  check_views(ir, board, "IR");
  check_views(right, board, "right");
  check_count(ir.size(), options, "depth-eye calibration");
  const std::vector<cv::Point3f> object = board_points(board);
  const cv::Matx33d Kd = camera_matrix(depth), Kr = camera_matrix(right_eye.k);
  const cv::Mat Dd = cv::Mat::zeros(1, 5, CV_64F), Dr = distortion_mat(right_eye);

  DepthEyeCalibration out;
  std::vector<cv::Point3d> a, b;
  for (std::size_t i = 0; i < ir.size(); ++i) {
    out.X_DepthBoard.push_back(solve_pose(object, ir[i], Kd, Dd));
    out.X_RightEyeBoard.push_back(solve_pose(object, right[i], Kr, Dr));
    for (const auto& p : object) {
      const glm::dvec3 pa = apply(out.X_DepthBoard.back(), to_glm(p));
      const glm::dvec3 pb = apply(out.X_RightEyeBoard.back(), to_glm(p));
      a.emplace_back(pa.x, pa.y, pa.z);
      b.emplace_back(pb.x, pb.y, pb.z);
    }
  }
  // The joint fit over every corner of every view averages the per-view poses with their
  // rotations handled properly; it seeds the reprojection refinement.
  const RigidTransform seed = fit_rigid_transform(a, b);
  cv::Mat R(to_cv(seed.rotation)), T = (cv::Mat_<double>(3, 1) << seed.translation_m.x,
                                        seed.translation_m.y, seed.translation_m.z);
  cv::Mat K1(Kd), D1 = Dd.clone(), K2(Kr), D2 = Dr.clone(), E, F, per_view;
  try {
    out.rms_px = cv::stereoCalibrate(
        repeat(object, ir.size()), ir, right, K1, D1, K2, D2, cv::Size(depth.width, depth.height),
        R, T, E, F, per_view, cv::CALIB_FIX_INTRINSIC | cv::CALIB_USE_EXTRINSIC_GUESS,
        cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 100, 1e-12));
  } catch (const cv::Exception& e) {
    throw CalibrationError(std::string("stereoCalibrate (depth to eye) failed: ") + e.what());
  }
  if (!std::isfinite(out.rms_px) || !finite(R) || !finite(T))
    throw CalibrationError("the depth-to-eye refinement gave no usable pose");
  out.X_RightEyeDepth = transform_from_cv(R, T);

  double ss_all = 0.0;
  std::size_t n_all = 0;
  for (std::size_t i = 0; i < ir.size(); ++i) {
    double ss = 0.0;
    for (const auto& p : object) {
      const glm::dvec3 via_depth =
          apply(out.X_RightEyeDepth, apply(out.X_DepthBoard[i], to_glm(p)));
      const glm::dvec3 via_eye = apply(out.X_RightEyeBoard[i], to_glm(p));
      const glm::dvec3 d = via_depth - via_eye;
      ss += glm::dot(d, d);
    }
    out.view_residual_mm.push_back(std::sqrt(ss / static_cast<double>(object.size())) * 1e3);
    ss_all += ss;
    n_all += object.size();
  }
  out.residual_mm = std::sqrt(ss_all / static_cast<double>(n_all)) * 1e3;

  if (depth_maps.empty()) return out;
  // The board plane in each depth map, against the IR pose's plane, and the plane-only estimate.
  const glm::dvec3 centre_Board((board.cols - 1) * board.square_m * 0.5,
                                (board.rows - 1) * board.square_m * 0.5, 0.0);
  std::vector<glm::dvec3> n_depth, n_right;
  std::vector<double> d_depth, d_right;
  for (std::size_t i = 0; i < ir.size(); ++i) {
    auto plane = fit_board_plane(depth_maps[i], depth, ir[i], board);
    if (!plane) {
      out.planes.push_back(DepthPlaneView{});
      continue;
    }
    const RigidTransform& X_DB = out.X_DepthBoard[i];
    const glm::dvec3 n_ir = X_DB.rotation[2];
    const glm::dvec3 c = apply(X_DB, centre_Board);
    plane->offset_to_ir_plane_mm = (plane->offset_m - glm::dot(plane->normal_Depth, c)) * 1e3;
    plane->angle_to_ir_plane_deg =
        std::acos(std::clamp(glm::dot(plane->normal_Depth, n_ir), -1.0, 1.0)) * 180.0 / kPi;
    out.planes.push_back(*plane);
    const RigidTransform& X_RB = out.X_RightEyeBoard[i];
    n_depth.push_back(plane->normal_Depth);
    d_depth.push_back(plane->offset_m);
    n_right.push_back(X_RB.rotation[2]);
    d_right.push_back(glm::dot(X_RB.rotation[2], X_RB.translation_m));
  }
  if (n_depth.size() < 3) return out;
  // Rotation: the one turning the depth planes' normals onto the eye's (orthogonal Procrustes);
  // translation: n_right . t = d_right - d_depth for each plane, least squares. Needs normals
  // spread in at least two directions besides the common one.
  cv::Matx33d H = cv::Matx33d::zeros();
  cv::Mat N(static_cast<int>(n_depth.size()), 3, CV_64F), rhs(N.rows, 1, CV_64F);
  for (std::size_t i = 0; i < n_depth.size(); ++i) {
    H += cv::Vec3d(n_depth[i].x, n_depth[i].y, n_depth[i].z) *
         cv::Vec3d(n_right[i].x, n_right[i].y, n_right[i].z).t();
    const int r = static_cast<int>(i);
    N.at<double>(r, 0) = n_right[i].x;
    N.at<double>(r, 1) = n_right[i].y;
    N.at<double>(r, 2) = n_right[i].z;
    rhs.at<double>(r) = d_right[i] - d_depth[i];
  }
  cv::Mat sv;
  cv::SVD::compute(N, sv, cv::SVD::NO_UV);
  // Normals within a few degrees of each other leave the translation across them unknown.
  if (sv.at<double>(2) < 0.05 * sv.at<double>(0)) return out;
  cv::Matx33d U, Vt;
  cv::Vec3d w;
  cv::SVD::compute(H, w, U, Vt);
  const cv::Matx33d V = Vt.t();
  const double det = cv::determinant(V * U.t());
  const cv::Matx33d Rp = V * cv::Matx33d(1, 0, 0, 0, 1, 0, 0, 0, det < 0 ? -1.0 : 1.0) * U.t();
  cv::Mat t;
  cv::solve(N, rhs, t, cv::DECOMP_SVD);
  out.X_RightEyeDepth_from_planes =
      RigidTransform{to_glm(Rp), {t.at<double>(0), t.at<double>(1), t.at<double>(2)}};
  return out;
}

}  // namespace telex::calib
