// SPDX-License-Identifier: MIT
// Shaded colour renders of synthetic scenes for the synthetic stereo source.
#include "telex/remote/synthetic_view.h"

#include <algorithm>
#include <array>
#include <cmath>

namespace telex::remote {

cv::Mat3b shade_render(const synth::Rendered& rendered) {
  static const std::array<cv::Vec3f, 8> kBase = {cv::Vec3f(180, 180, 180), cv::Vec3f(90, 140, 200),
                                                 cv::Vec3f(60, 170, 90),   cv::Vec3f(200, 120, 60),
                                                 cv::Vec3f(80, 80, 210),   cv::Vec3f(190, 90, 170),
                                                 cv::Vec3f(60, 200, 200),  cv::Vec3f(140, 110, 90)};
  const cv::Mat1f& z = rendered.true_depth_m;
  cv::Mat3b out(z.size(), cv::Vec3b(0, 0, 0));
  for (int y = 0; y < z.rows; ++y) {
    for (int x = 0; x < z.cols; ++x) {
      const float depth = z(y, x);
      if (!(depth > 0.0f)) continue;
      const cv::Vec3f n = rendered.true_normals(y, x);
      // Head light along the viewing axis: normals face the camera, so -n_z is the cosine.
      const float lambert = std::clamp(-n[2], 0.0f, 1.0f);
      const float fade = 1.0f / (1.0f + 0.35f * depth * depth);
      const int id = rendered.object_id.empty() ? 0 : std::max(0, rendered.object_id(y, x));
      const cv::Vec3f c =
          kBase[static_cast<std::size_t>(id) % kBase.size()] * (0.25f + 0.75f * lambert) * fade;
      out(y, x) = cv::Vec3b(cv::saturate_cast<uchar>(c[0]), cv::saturate_cast<uchar>(c[1]),
                            cv::saturate_cast<uchar>(c[2]));
    }
  }
  return out;
}

StereoViews render_stereo_views(const synth::Scene& scene, const Intrinsics& intrinsics,
                                double interpupillary_m) {
  const auto ideal = synth::SensorModel::ideal();
  StereoViews v;
  v.right_bgr = shade_render(synth::render(scene, intrinsics, ideal));
  v.left_bgr = shade_render(
      synth::render_from(scene, intrinsics, glm::dvec3(-interpupillary_m, 0.0, 0.0), ideal));
  return v;
}

}  // namespace telex::remote
