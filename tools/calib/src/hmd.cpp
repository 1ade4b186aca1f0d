// SPDX-License-Identifier: MIT
// The headset's STAGE space in the NatNet frame: the poses CSV and OpenCV's robot-world /
// hand-eye solve with its residuals.
#include "telex/calib/hmd.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <glm/gtc/quaternion.hpp>
#include <opencv2/calib3d.hpp>
#include <string>

#include "csv_cells.h"

namespace telex::calib {
namespace {

constexpr double kDeg = 180.0 / 3.14159265358979323846;
constexpr std::size_t kColumns = std::size(kHmdPoseColumns);

std::string num(double v, int decimals) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  return buf;
}

std::string expected_header() {
  std::string h;
  for (const char* c : kHmdPoseColumns) h += (h.empty() ? "" : ",") + std::string(c);
  return h;
}

cv::Mat to_cv(const glm::dmat3& r) {
  cv::Mat m(3, 3, CV_64F);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) m.at<double>(i, j) = r[j][i];  // glm is column-major
  return m;
}

cv::Mat to_cv(const glm::dvec3& t) { return (cv::Mat_<double>(3, 1) << t.x, t.y, t.z); }

// The rotation nearest `m` (the solver's linear estimate need not be exactly orthonormal, and the
// rig refuses one that is not to 1e-6).
cv::Mat nearest_rotation(const cv::Mat& m) {
  cv::Mat r;
  m.convertTo(r, CV_64F);
  const cv::SVD svd(r);
  cv::Mat out = svd.u * svd.vt;
  if (cv::determinant(out) < 0) out = svd.u * cv::Mat::diag(cv::Mat(cv::Vec3d(1, 1, -1))) * svd.vt;
  return out;
}

// Columns [first, first + 7) of `v`: x, y, z, qx, qy, qz, qw as a transform.
RigidTransform pose_of(const std::array<double, kColumns>& v, std::size_t first,
                       const std::string& where) {
  const glm::dquat q(v[first + 6], v[first + 3], v[first + 4], v[first + 5]);  // w, x, y, z
  const double n = glm::length(q);
  if (std::abs(n - 1.0) > 0.01)
    throw PoseCsvError(where + " columns " + std::to_string(first + 4) + "-" +
                       std::to_string(first + 7) + " (" + kHmdPoseColumns[first + 3] + ".." +
                       kHmdPoseColumns[first + 6] + "): the quaternion's norm is " + num(n, 4) +
                       ", not 1 (x, y, z, w order)");
  return {glm::mat3_cast(q / n), {v[first], v[first + 1], v[first + 2]}};
}

void check_header(const std::vector<std::string>& cells, const std::string& where) {
  for (std::size_t i = 0; i < kColumns; ++i) {
    const std::string got = i < cells.size() ? cells[i] : std::string("(nothing)");
    if (got != kHmdPoseColumns[i])
      throw PoseCsvError(where + " column " + std::to_string(i + 1) + ": the header has '" + got +
                         "' where '" + kHmdPoseColumns[i] + "' belongs; the header must be " +
                         expected_header());
  }
  if (cells.size() != kColumns)
    throw PoseCsvError(where + ": the header has " + std::to_string(cells.size()) +
                       " columns, expected " + std::to_string(kColumns) + ": " + expected_header());
}

}  // namespace

std::vector<HmdPoseSample> load_hmd_poses_csv(const std::filesystem::path& path) {
  std::ifstream in(path);
  const std::string file = "poses CSV " + path.string();
  if (!in) throw PoseCsvError(file + ": cannot open");
  std::vector<HmdPoseSample> poses;
  std::string line;
  int line_no = 0;
  bool header = false;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.empty() || line == "\r" || line[0] == '#') continue;
    const std::string where = file + " line " + std::to_string(line_no);
    const auto cells = detail::split_csv(line);
    if (!header) {
      check_header(cells, where);
      header = true;
      continue;
    }
    if (cells.size() != kColumns)
      throw PoseCsvError(where + ": " + std::to_string(cells.size()) + " columns, the header has " +
                         std::to_string(kColumns));
    std::array<double, kColumns> v{};
    for (std::size_t i = 0; i < kColumns; ++i)
      if (!detail::to_double(cells[i], v[i]))
        throw PoseCsvError(where + " column " + std::to_string(i + 1) + " (" + kHmdPoseColumns[i] +
                           "): '" + cells[i] + "' is not a number");
    poses.push_back({line_no, v[0], pose_of(v, 1, where), pose_of(v, 8, where)});
  }
  if (!header) throw PoseCsvError(file + ": empty (expected the header " + expected_header() + ")");
  if (poses.empty()) throw PoseCsvError(file + ": a header but no rows");
  return poses;
}

TurnSpread turn_spread(const std::vector<HmdPoseSample>& poses, double min_turn_deg) {
  TurnSpread s;
  if (poses.empty()) return s;
  const glm::dmat3 R0t = glm::transpose(poses.front().X_StageView.rotation);
  cv::Matx33d scatter = cv::Matx33d::zeros();
  for (const HmdPoseSample& p : poses) {
    // The turn from the first pose, in the first pose's view frame: turns about one axis give
    // the same axis whichever pose is first.
    const cv::Vec3d r = rotation_vector_rad(R0t * p.X_StageView.rotation);
    const double angle_deg = cv::norm(r) * kDeg;
    s.max_turn_deg = std::max(s.max_turn_deg, angle_deg);
    if (angle_deg < min_turn_deg) continue;
    const cv::Vec3d a = r / cv::norm(r);
    scatter += a * a.t();
    ++s.turns;
  }
  if (s.turns < 2) return s;
  cv::Mat eigenvalues;
  cv::eigen(scatter, eigenvalues);  // descending
  const double l1 = eigenvalues.at<double>(0), l2 = std::max(eigenvalues.at<double>(1), 0.0);
  s.axis_spread_deg = 2.0 * std::atan(std::sqrt(l2 / l1)) * kDeg;
  return s;
}

void hmd_residuals(const std::vector<HmdPoseSample>& poses, HmdCalibration& c) {
  c.position_mm.clear();
  c.rotation_deg.clear();
  double sum_mm2 = 0.0, sum_deg2 = 0.0;
  for (const HmdPoseSample& p : poses) {
    const RigidTransform via_body = compose(p.X_NatNetBody, c.X_BodyView);
    const RigidTransform via_stage = compose(c.X_NatNetStage, p.X_StageView);
    const double mm = glm::length(via_body.translation_m - via_stage.translation_m) * 1e3;
    const double deg = rotation_angle_between_rad(via_body.rotation, via_stage.rotation) * kDeg;
    c.position_mm.push_back(mm);
    c.rotation_deg.push_back(deg);
    sum_mm2 += mm * mm;
    sum_deg2 += deg * deg;
  }
  const double n = static_cast<double>(std::max<std::size_t>(poses.size(), 1));
  c.rms_mm = std::sqrt(sum_mm2 / n);
  c.rms_deg = std::sqrt(sum_deg2 / n);
}

HmdCalibration calibrate_hmd(const std::vector<HmdPoseSample>& poses, const HmdCalibOptions& o) {
  const int n = static_cast<int>(poses.size());
  if (n < std::max(o.min_poses, 3))
    throw CalibrationError(std::to_string(n) + " poses; at least " +
                           std::to_string(std::max(o.min_poses, 3)) +
                           " are needed (turn the head through a few poses: yaw, pitch and roll)");
  const TurnSpread s = turn_spread(poses, o.min_turn_deg);
  if (s.turns < 2)
    throw CalibrationError("the head hardly turned: " + std::to_string(s.turns) +
                           " poses turned at least " + num(o.min_turn_deg, 1) +
                           " deg from the first (the most: " + num(s.max_turn_deg, 1) +
                           " deg); turn it through a few poses about different axes");
  if (s.axis_spread_deg < o.min_axis_spread_deg)
    throw CalibrationError("the head turned about one axis only: the turns' axes spread " +
                           num(s.axis_spread_deg, 1) + " deg (at least " +
                           num(o.min_axis_spread_deg, 1) +
                           "); turn it about another axis too (nod as well as shake, or tilt)");
  std::vector<cv::Mat> R_body, t_body, R_view, t_view;
  for (const HmdPoseSample& p : poses) {
    R_body.push_back(to_cv(p.X_NatNetBody.rotation));
    t_body.push_back(to_cv(p.X_NatNetBody.translation_m));
    R_view.push_back(to_cv(p.X_StageView.rotation));
    t_view.push_back(to_cv(p.X_StageView.translation_m));
  }
  // OpenCV's A X = Z B with A = X_NatNetBody_i ("world to camera"), B = X_StageView_i ("base to
  // gripper"): X ("base to world") is X_BodyView, Z ("gripper to camera") is X_NatNetStage.
  cv::Mat R_x, t_x, R_z, t_z;
  try {
    cv::calibrateRobotWorldHandEye(R_body, t_body, R_view, t_view, R_x, t_x, R_z, t_z,
                                   cv::CALIB_ROBOT_WORLD_HAND_EYE_SHAH);
  } catch (const cv::Exception& e) {
    throw CalibrationError(std::string("OpenCV's calibrateRobotWorldHandEye failed: ") + e.what());
  }
  if (R_x.empty() || R_z.empty() || !cv::checkRange(R_x) || !cv::checkRange(t_x) ||
      !cv::checkRange(R_z) || !cv::checkRange(t_z))
    throw CalibrationError("OpenCV's calibrateRobotWorldHandEye gave no finite solution");
  HmdCalibration c;
  c.X_BodyView = transform_from_cv(nearest_rotation(R_x), t_x);
  c.X_NatNetStage = transform_from_cv(nearest_rotation(R_z), t_z);
  c.max_turn_deg = s.max_turn_deg;
  c.axis_spread_deg = s.axis_spread_deg;
  hmd_residuals(poses, c);
  if (c.rms_mm > o.max_rms_mm || c.rms_deg > o.max_rms_deg) {
    std::size_t worst = 0;
    for (std::size_t i = 1; i < poses.size(); ++i)
      if (c.position_mm[i] / o.max_rms_mm + c.rotation_deg[i] / o.max_rms_deg >
          c.position_mm[worst] / o.max_rms_mm + c.rotation_deg[worst] / o.max_rms_deg)
        worst = i;
    throw CalibrationError(
        "the fit leaves RMS residuals of " + num(c.rms_mm, 1) + " mm and " + num(c.rms_deg, 2) +
        " deg (at most " + num(o.max_rms_mm, 1) + " mm and " + num(o.max_rms_deg, 2) +
        " deg); the worst pose, line " + std::to_string(poses[worst].line) + ", is off " +
        num(c.position_mm[worst], 1) + " mm and " + num(c.rotation_deg[worst], 2) +
        " deg: are both poses of a row taken at the same moment, and the columns in the "
        "header's order?");
  }
  return c;
}

}  // namespace telex::calib
