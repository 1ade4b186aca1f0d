// SPDX-License-Identifier: MIT
// Fig. 7's layout: the interaction view beside the full-frame normal map with touch vectors.
#include "telex/local/view/fig7_view.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>

#include "telex/common/colorize.h"
#include "telex/common/normals.h"
#include "telex/local/view/operator_view.h"
#include "telex/local/view/pinhole.h"

namespace telex::local {
namespace {

// The surface's normals cover the scene when at least half the pixels with depth have one.
bool covers_scene(const Surface& s, const cv::Mat1w& depth_mm) {
  if (s.normals.size() != depth_mm.size()) return false;
  std::size_t with_depth = 0, with_normal = 0;
  for (int y = 0; y < depth_mm.rows; y += 2)
    for (int x = 0; x < depth_mm.cols; x += 2) {
      if (depth_mm(y, x) == 0) continue;
      ++with_depth;
      const cv::Vec3f& n = s.normals(y, x);
      with_normal += n[0] != 0.0f || n[1] != 0.0f || n[2] != 0.0f;
    }
  return with_depth > 0 && 2 * with_normal >= with_depth;
}

// An arrow that stays visible when the vector points nearly at the camera: at least `min_px`.
void arrow(cv::Mat3b& img, const Intrinsics& k, const glm::dvec3& from, const glm::dvec3& to,
           const cv::Scalar& bgr, int thick, double min_px) {
  const auto a = project(k, from), b = project(k, to);
  if (!a || !b) return;
  cv::Point2d d = *b - *a;
  const double len = std::hypot(d.x, d.y);
  if (len < 1e-6) return;
  if (len < min_px) d *= min_px / len;
  cv::arrowedLine(img, *a, *a + d, bgr, thick, cv::LINE_AA, 0, 0.25);
}

}  // namespace

cv::Mat3f display_normals(const cv::Mat1w& depth_mm, const Intrinsics& k, const Surface* surface,
                          int reduce) {
  if (depth_mm.empty()) return {};
  if (surface != nullptr && covers_scene(*surface, depth_mm)) return surface->normals;
  reduce = std::max(1, reduce);
  const cv::Size small(std::max(1, depth_mm.cols / reduce), std::max(1, depth_mm.rows / reduce));
  cv::Mat1w depth_small;
  cv::resize(depth_mm, depth_small, small, 0, 0, cv::INTER_NEAREST);
  cv::Mat3f normals_small;
  compute_normals(depth_m_from_mm(depth_small), k.scaled(small.width, small.height), normals_small);
  cv::Mat3f out;
  cv::resize(normals_small, out, depth_mm.size(), 0, 0, cv::INTER_NEAREST);
  return out;
}

void draw_touch_vectors(cv::Mat3b& panel, const Intrinsics& k,
                        const std::array<FingertipForce, kFingerCount>& forces,
                        double arrow_m_per_N) {
  static constexpr std::array<const char*, kFingerCount> kName{"T", "I", "M", "R", "L"};
  const int thick = std::max(2, panel.cols / 320);
  // Pressure points mostly at the camera: the normal and the force keep a visible length, the
  // normal the longer, so both clear the god-point's ring.
  const double min_force_px = 10.0 * thick, min_normal_px = 15.0 * thick;
  for (std::size_t i = 0; i < kFingerCount; ++i) {
    const FingertipForce& f = forces[i];
    if (!f.contact) continue;
    const glm::dvec3 p = f.p_ModelProxy;
    const auto at = project(k, p);
    if (!at) continue;
    arrow(panel, k, p, p + f.normal_Model * 0.03, {255, 255, 255}, thick, min_normal_px);
    arrow(panel, k, p, p + f.tangential_force_N * arrow_m_per_N, {255, 0, 255}, thick, 0.0);
    arrow(panel, k, p, p + f.force_N * arrow_m_per_N, {0, 230, 255}, thick, min_force_px);
    // The god-point: a dark-edged ring that reads on any normal colour.
    cv::circle(panel, *at, 3 * thick, {0, 0, 0}, thick + 2, cv::LINE_AA);
    cv::circle(panel, *at, 3 * thick, {0, 230, 255}, thick, cv::LINE_AA);
    char label[32];
    std::snprintf(label, sizeof label, "%s %.1f N", kName[i], glm::length(f.force_N));
    const cv::Point org(static_cast<int>(at->x) + 4 * thick, static_cast<int>(at->y) - 4 * thick);
    const double scale = 0.25 * thick;
    cv::putText(panel, label, org, cv::FONT_HERSHEY_SIMPLEX, scale, {0, 0, 0}, thick + 2,
                cv::LINE_AA);
    cv::putText(panel, label, org, cv::FONT_HERSHEY_SIMPLEX, scale, {255, 255, 255}, thick,
                cv::LINE_AA);
  }
}

cv::Mat3b fig7_layout(const cv::Mat3b& interaction, const Intrinsics& k_view,
                      const cv::Mat3f& normals, const Intrinsics& k_depth,
                      const std::array<FingertipForce, kFingerCount>& forces,
                      double arrow_m_per_N) {
  cv::Mat3b panel;
  if (normals.empty())
    panel = cv::Mat3b(interaction.size(), cv::Vec3b(0, 0, 0));
  else
    panel = resample_pinhole(colorize_normals(normals), k_depth, k_view, cv::INTER_NEAREST);
  draw_touch_vectors(panel, k_view, forces, arrow_m_per_N);
  const std::string legend =
      "normal map: god-point, normal (white), force (yellow), shear (magenta)";
  const double scale = 0.35 * std::max(1, panel.cols / 640);
  cv::putText(panel, legend, {8, panel.rows - 10}, cv::FONT_HERSHEY_SIMPLEX, scale, {0, 0, 0}, 3,
              cv::LINE_AA);
  cv::putText(panel, legend, {8, panel.rows - 10}, cv::FONT_HERSHEY_SIMPLEX, scale, {255, 255, 255},
              1, cv::LINE_AA);
  cv::Mat3b out;
  cv::hconcat(interaction, panel, out);
  return out;
}

}  // namespace telex::local
