// SPDX-License-Identifier: MIT
// Pinhole resampling for the view (pinhole.h).
#include "telex/local/view/pinhole.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

namespace telex::local {

Intrinsics eye_intrinsics(const Intrinsics& k, cv::Size size) {
  const double s = std::max(static_cast<double>(size.width) / k.width,
                            static_cast<double>(size.height) / k.height);
  Intrinsics out = k;
  out.fx = k.fx * s;
  out.fy = k.fy * s;
  // Pixel centres scale as (c + 0.5) s - 0.5; the overhang of the scaled image is cut evenly.
  out.cx = (k.cx + 0.5) * s - 0.5 - (k.width * s - size.width) / 2.0;
  out.cy = (k.cy + 0.5) * s - 0.5 - (k.height * s - size.height) / 2.0;
  out.width = size.width;
  out.height = size.height;
  return out;
}

cv::Mat resample_pinhole(const cv::Mat& image, const Intrinsics& from, const Intrinsics& to,
                         int interpolation, const cv::Scalar& border) {
  if (image.empty() || (from == to && image.cols == to.width && image.rows == to.height))
    return image;
  // Output pixel (u, v) sees the ray ((u - to.cx) / to.fx, ...): in `image` at this affine map.
  const double sx = from.fx / to.fx, sy = from.fy / to.fy;
  const cv::Matx23d M(sx, 0.0, from.cx - sx * to.cx, 0.0, sy, from.cy - sy * to.cy);
  cv::Mat out;
  cv::warpAffine(image, out, M, {to.width, to.height}, interpolation | cv::WARP_INVERSE_MAP,
                 cv::BORDER_CONSTANT, border);
  return out;
}

cv::Mat resample_pinhole(const cv::Mat& image, const Intrinsics& from, const Intrinsics& to,
                         const glm::dmat3& R_FromTo, int interpolation, const cv::Scalar& border) {
  if (R_FromTo == glm::dmat3(1.0) || image.empty())
    return resample_pinhole(image, from, to, interpolation, border);
  // Output pixel (u, v) sees the ray K_to^-1 (u, v, 1) of `to`, R_FromTo times it in `from`.
  const cv::Matx33d K_from(from.fx, 0.0, from.cx, 0.0, from.fy, from.cy, 0.0, 0.0, 1.0);
  const cv::Matx33d K_to_inv(1.0 / to.fx, 0.0, -to.cx / to.fx, 0.0, 1.0 / to.fy, -to.cy / to.fy,
                             0.0, 0.0, 1.0);
  cv::Matx33d R;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) R(r, c) = R_FromTo[c][r];  // glm is column-major
  cv::Mat out;
  cv::warpPerspective(image, out, cv::Mat(K_from * R * K_to_inv), {to.width, to.height},
                      interpolation | cv::WARP_INVERSE_MAP, cv::BORDER_CONSTANT, border);
  return out;
}

cv::Mat1w resample_depth_turned(const cv::Mat1w& depth_mm, const Intrinsics& from,
                                const Intrinsics& to, const glm::dmat3& R_FromTo) {
  if (R_FromTo == glm::dmat3(1.0) || depth_mm.empty())
    return resample_pinhole(depth_mm, from, to, cv::INTER_NEAREST);
  cv::Mat1w out(to.height, to.width, std::uint16_t{0});
  // A point of `from` seen along d_To has z_To = (R_FromTo^T p_From).z: R_FromTo's third column.
  const glm::dvec3 z_axis_From = R_FromTo[2];
  for (int v = 0; v < to.height; ++v) {
    std::uint16_t* row = out.ptr<std::uint16_t>(v);
    for (int u = 0; u < to.width; ++u) {
      const glm::dvec3 d_From =
          R_FromTo * glm::dvec3((u - to.cx) / to.fx, (v - to.cy) / to.fy, 1.0);
      if (!(d_From.z > 0.0)) continue;
      const double x = std::floor(from.fx * d_From.x / d_From.z + from.cx + 0.5);
      const double y = std::floor(from.fy * d_From.y / d_From.z + from.cy + 0.5);
      if (!(x >= 0.0 && y >= 0.0 && x < depth_mm.cols && y < depth_mm.rows)) continue;
      const std::uint16_t z_mm = depth_mm(static_cast<int>(y), static_cast<int>(x));
      if (z_mm == 0) continue;
      // The sampled pixel's own point, exact: its ray times its depth.
      const glm::dvec3 p_From((x - from.cx) / from.fx, (y - from.cy) / from.fy, 1.0);
      const double z_to = glm::dot(z_axis_From, p_From) * z_mm;
      if (z_to > 0.5 && z_to < 65535.5) row[u] = static_cast<std::uint16_t>(std::lround(z_to));
    }
  }
  return out;
}

}  // namespace telex::local
