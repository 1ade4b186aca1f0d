// SPDX-License-Identifier: MIT
// Operator view rendering with OpenCV drawing primitives.
#include "telex/local/view/operator_view.h"

#include <cmath>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "telex/common/colorize.h"
#include "telex/local/view/status_band.h"

namespace telex::local {
namespace {
constexpr std::uint16_t kViewNearMm = 400;
constexpr std::uint16_t kViewFarMm = 2500;
// Phalanx lengths (distal first) drawn back along the finger axis when the tracker gives only
// fingertips (scripted hands).
constexpr double kPhalanxM[3] = {0.022, 0.025, 0.045};
const cv::Scalar kWindowOutlineBgr{0, 230, 255};
}  // namespace

std::vector<cv::Rect> haptic_windows(const Surface* surface, const cv::Mat3f& shown) {
  if (surface == nullptr || shown.data == surface->normals.data ||
      shown.size() != surface->normals.size())
    return {};
  const cv::Mat3f& normals = surface->normals;
  cv::Mat1b set(normals.size(), std::uint8_t{0});
  for (int y = 0; y < normals.rows; ++y)
    for (int x = 0; x < normals.cols; ++x) {
      const cv::Vec3f& n = normals(y, x);
      set(y, x) = (n[0] != 0.0f || n[1] != 0.0f || n[2] != 0.0f) ? 255 : 0;
    }
  cv::Mat1i labels, stats;
  cv::Mat centroids;
  const int count = cv::connectedComponentsWithStats(set, labels, stats, centroids, 8);
  std::vector<cv::Rect> out;
  for (int i = 1; i < count; ++i)
    out.emplace_back(stats(i, cv::CC_STAT_LEFT), stats(i, cv::CC_STAT_TOP),
                     stats(i, cv::CC_STAT_WIDTH), stats(i, cv::CC_STAT_HEIGHT));
  return out;
}

cv::Mat3b normal_inset(const cv::Mat3f& normals, std::span<const cv::Rect> windows, int image_cols,
                       int image_rows) {
  if (normals.empty()) return {};
  const int w = image_cols / 4, h = w * normals.rows / normals.cols;
  if (w <= 0 || h <= 0 || h + 5 > image_rows) return {};
  cv::Mat3b small;
  cv::resize(colorize_normals(normals), small, {w, h}, 0, 0, cv::INTER_AREA);
  const double s = static_cast<double>(w) / normals.cols;
  for (const cv::Rect& r : windows)
    cv::rectangle(small, cv::Point(static_cast<int>(r.x * s), static_cast<int>(r.y * s)),
                  cv::Point(static_cast<int>(r.br().x * s), static_cast<int>(r.br().y * s)),
                  kWindowOutlineBgr, 1);
  return small;
}

void paste_normal_inset(cv::Mat3b& img, const cv::Mat3b& inset) {
  if (inset.empty() || inset.cols + 5 > img.cols || inset.rows + 5 > img.rows) return;
  const cv::Rect at(img.cols - inset.cols - 4, 4, inset.cols, inset.rows);
  inset.copyTo(img(at));
  cv::rectangle(img, cv::Rect(at.x - 1, at.y - 1, at.width + 2, at.height + 2), {255, 255, 255}, 1);
}

void draw_normal_inset(cv::Mat3b& img, const cv::Mat3f& normals,
                       std::span<const cv::Rect> windows) {
  paste_normal_inset(img, normal_inset(normals, windows, img.cols, img.rows));
}

std::optional<cv::Point2d> project(const Intrinsics& k, const glm::dvec3& p) {
  if (!(p.z > 1e-3) || !std::isfinite(p.x) || !std::isfinite(p.y)) return std::nullopt;
  return cv::Point2d(k.fx * p.x / p.z + k.cx, k.fy * p.y / p.z + k.cy);
}

cv::Mat3b render_operator_view(const ViewInputs& in) {
  cv::Mat3b img;
  if (!in.camera_bgr.empty()) {
    img = in.camera_bgr.clone();
  } else if (!in.depth_mm.empty()) {
    // A fixed range: a percentile range would stretch the sensor noise of a flat wall over the
    // whole colour map.
    img = colorize_depth(in.depth_mm, kViewNearMm, kViewFarMm);
  } else {
    img = cv::Mat3b(480, 640, cv::Vec3b(32, 32, 32));
  }
  if (in.surface == nullptr) {
    cv::putText(img, "waiting for the remote surface", {10, 24}, cv::FONT_HERSHEY_SIMPLEX, 0.6,
                {255, 255, 255}, 1, cv::LINE_AA);
    return img;
  }
  // The camera image may be larger or smaller than the depth: scale the intrinsics to it.
  const Intrinsics k = in.surface->intrinsics.scaled(img.cols, img.rows);
  const int thick = std::max(1, img.cols / 320);

  const cv::Mat3f& shown = in.normals.empty() ? in.surface->normals : in.normals;
  draw_normal_inset(img, shown, haptic_windows(in.surface, shown));

  // Virtual hand: segments from wrist through the joints to the fingertips.
  const cv::Scalar bone(230, 230, 230), tip_free(60, 220, 60), tip_contact(40, 40, 255);
  for (int f = 0; f < kFingerCount; ++f) {
    const auto& tip = in.hand.tips[static_cast<std::size_t>(f)];
    if (!tip.valid) continue;
    if (in.hand.skeleton_valid) {
      auto prev = project(k, in.hand.wrist_camera);
      for (const auto& j : in.hand.joints_camera[static_cast<std::size_t>(f)]) {
        auto cur = project(k, j);
        if (prev && cur) cv::line(img, *prev, *cur, bone, 2 * thick, cv::LINE_AA);
        prev = cur;
      }
    } else {
      // Only the fingertip is known: draw a straight finger back along its axis.
      glm::dvec3 joint = tip.p_CameraFingertip;
      for (double len : kPhalanxM) {
        const glm::dvec3 next = joint - tip.axis_Camera * len;
        auto a = project(k, joint), b = project(k, next);
        if (a && b) cv::line(img, *a, *b, bone, 3 * thick, cv::LINE_AA);
        if (b) cv::circle(img, *b, 2 * thick, bone, cv::FILLED, cv::LINE_AA);
        joint = next;
      }
    }
    const auto p = project(k, tip.p_CameraFingertip);
    if (!p) continue;
    const auto& force = in.forces[static_cast<std::size_t>(f)];
    const int radius = std::max(4, static_cast<int>(k.fx * 0.009 / tip.p_CameraFingertip.z));
    // Force arrow: the force vector drawn in the scene from the fingertip, then projected.
    const double mag = glm::length(force.force_N);
    if (mag > 1e-3 && std::isfinite(mag)) {
      const glm::dvec3 end = tip.p_CameraFingertip + force.force_N * in.arrow_m_per_N;
      auto q = project(k, end);
      if (q) {
        // Pressure points straight at the camera: keep the arrow visible with a minimum length.
        cv::Point2d d = *q - *p;
        const double len = std::hypot(d.x, d.y);
        const double min_len = 12.0 * thick + 8.0 * mag * thick;
        if (len < min_len) d = (len > 1e-6 ? d * (min_len / len) : cv::Point2d(0, -min_len));
        cv::arrowedLine(img, *p, *p + d, {0, 200, 255}, 2 * thick, cv::LINE_AA, 0, 0.25);
      }
      char buf[32];
      std::snprintf(buf, sizeof buf, "%.2f N", mag);
      cv::putText(img, buf, *p + cv::Point2d(radius + 4, -radius), cv::FONT_HERSHEY_SIMPLEX,
                  0.45 * thick, {0, 200, 255}, thick, cv::LINE_AA);
    }
    // The fingertip last, so it stays visible on top of its arrow.
    cv::circle(img, *p, radius, force.contact ? tip_contact : tip_free, cv::FILLED, cv::LINE_AA);
  }
  draw_status_band(img, in.status, 0.45 * thick, thick);
  return img;
}

}  // namespace telex::local
