// SPDX-License-Identifier: MIT
// What `telex calibrate` reports: rotations in degrees for JSON, and the depth-eye result.
#include "calibrate_report.h"

#include <algorithm>
#include <cstdio>
#include <iostream>

namespace telex::tool {
namespace {

constexpr double kDeg = 180.0 / 3.14159265358979323846;

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

double rotation_angle_deg(const glm::dmat3& r) {
  return cv::norm(calib::rotation_vector_rad(r)) * kDeg;
}

}  // namespace

std::vector<double> rotation_vector_deg(const glm::dmat3& r) {
  const cv::Vec3d v = calib::rotation_vector_rad(r);
  return {v[0] * kDeg, v[1] * kDeg, v[2] * kDeg};
}

std::vector<double> vec(const glm::dvec3& v) { return {v.x, v.y, v.z}; }

nlohmann::json depth_plane_summary(const calib::DepthEyeCalibration& c) {
  std::vector<double> offset, angle, fit;
  for (const auto& pl : c.planes)
    if (pl.used) {
      offset.push_back(pl.offset_to_ir_plane_mm);
      angle.push_back(pl.angle_to_ir_plane_deg);
      fit.push_back(pl.fit_rms_mm);
    }
  nlohmann::json planes = {{"views", offset.size()},
                           {"offset_to_ir_plane_mm_median", median(offset)},
                           {"angle_to_ir_plane_deg_median", median(angle)},
                           {"fit_rms_mm_median", median(fit)}};
  if (c.X_RightEyeDepth_from_planes) {
    const RigidTransform& x = *c.X_RightEyeDepth_from_planes;
    planes["from_planes"] = {
        {"translation_m", vec(x.translation_m)},
        {"rotation_deg", rotation_vector_deg(x.rotation)},
        {"differs_mm", glm::length(x.translation_m - c.X_RightEyeDepth.translation_m) * 1e3},
        {"differs_deg",
         calib::rotation_angle_between_rad(x.rotation, c.X_RightEyeDepth.rotation) * kDeg}};
  }
  return planes;
}

void print_depth_eye_json(const DepthEyeResult& r) {
  nlohmann::json j{{"translation_m", vec(r.c.X_RightEyeDepth.translation_m)},
                   {"rotation_deg", rotation_vector_deg(r.c.X_RightEyeDepth.rotation)},
                   {"rotation_angle_deg", rotation_angle_deg(r.c.X_RightEyeDepth.rotation)},
                   {"residual_mm", r.c.residual_mm},
                   {"rms_px", r.c.rms_px},
                   {"views", r.views},
                   {"views_used", r.views_used},
                   {"skipped", r.skipped},
                   {"view_residual_mm", r.c.view_residual_mm},
                   {"rig", r.rig}};
  if (!r.planes.is_null()) j["depth_planes"] = r.planes;
  std::cout << j.dump(2) << "\n";
}

void print_depth_eye_text(const DepthEyeResult& r) {
  const glm::dvec3 t = r.c.X_RightEyeDepth.translation_m;
  const std::vector<double> rot_deg = rotation_vector_deg(r.c.X_RightEyeDepth.rotation);
  std::printf("views: %zu of %zu used\n", r.views_used, r.views);
  std::printf(
      "depth in the right eye: t = [%.2f %.2f %.2f] mm, rotation vector [%.3f %.3f %.3f] "
      "deg (%.3f deg)\n",
      t.x * 1e3, t.y * 1e3, t.z * 1e3, rot_deg[0], rot_deg[1], rot_deg[2],
      rotation_angle_deg(r.c.X_RightEyeDepth.rotation));
  std::printf(
      "residual %.2f mm (board corners via the depth pose vs the eye's), reprojection "
      "RMS %.3f px\n",
      r.c.residual_mm, r.c.rms_px);
  if (!r.planes.is_null()) {
    const nlohmann::json& planes = r.planes;
    std::printf(
        "depth maps: board plane vs the IR pose's plane: median offset %.2f mm, angle "
        "%.3f deg, fit RMS %.2f mm (%d views)\n",
        planes["offset_to_ir_plane_mm_median"].get<double>(),
        planes["angle_to_ir_plane_deg_median"].get<double>(),
        planes["fit_rms_mm_median"].get<double>(), planes["views"].get<int>());
    if (planes.contains("from_planes"))
      std::printf("from the planes alone: differs by %.2f mm and %.3f deg\n",
                  planes["from_planes"]["differs_mm"].get<double>(),
                  planes["from_planes"]["differs_deg"].get<double>());
  }
  std::printf("wrote extrinsics.right_eye_from_depth%s into %s\n",
              r.wrote_depth ? " and depth" : "", r.rig.c_str());
}

}  // namespace telex::tool
