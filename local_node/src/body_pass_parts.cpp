// SPDX-License-Identifier: MIT
// The body pass's CPU side: which capsules blend, the skin's exposure, and where the remote depth
// comes near a fingertip (per-tile depth ranges) so the contact shadows shade only there.
#include <algorithm>
#include <cmath>
#include <cstddef>

#include "body_pass.h"

namespace telex::local {

std::vector<std::array<std::int32_t, kMaxBlendNeighbours>> blend_neighbours(
    std::span<const Capsule> capsules) {
  constexpr double kSameEnd_m = 1e-3;
  const auto near = [](const glm::dvec3& p, const glm::dvec3& q) {
    return glm::length(p - q) < kSameEnd_m;
  };
  std::vector<std::array<std::int32_t, kMaxBlendNeighbours>> out(capsules.size());
  for (std::size_t i = 0; i < capsules.size(); ++i) {
    out[i].fill(-1);
    std::size_t n = 0;
    const Capsule& c = capsules[i];
    for (std::size_t j = 0; j < capsules.size() && n < kMaxBlendNeighbours; ++j) {
      const Capsule& o = capsules[j];
      if (j == i || c.lit != o.lit) continue;
      if (near(c.a, o.a) || near(c.a, o.b) || near(c.b, o.a) || near(c.b, o.b))
        out[i][n++] = static_cast<std::int32_t>(j);
    }
  }
  return out;
}

float exposure_from_image(const cv::Mat3b& bgr) {
  if (bgr.empty()) return 1.0f;
  // Every 8th pixel of every 8th row is plenty for a mean.
  double sum = 0.0;
  std::size_t n = 0;
  for (int y = 0; y < bgr.rows; y += 8)
    for (int x = 0; x < bgr.cols; x += 8) {
      const cv::Vec3b& c = bgr(y, x);
      sum += 0.114 * c[0] + 0.587 * c[1] + 0.299 * c[2];
      ++n;
    }
  // The square root keeps a dark room's skin readable while still following its brightness.
  return static_cast<float>(std::clamp(std::sqrt(sum / static_cast<double>(n) / 118.0), 0.3, 1.5));
}

double window_depth_of(double z_m) {
  constexpr double n = StereoRenderer::kNear_m, f = StereoRenderer::kFar_m;
  const double z = std::clamp(z_m, n, f);
  return 0.5 * ((f + n) / (f - n) - 2.0 * f * n / ((f - n) * z)) + 0.5;
}

void depth_tiles(const cv::Mat1f& depth, cv::Mat2f& tiles) {
  tiles.create((depth.rows + kDepthTile - 1) / kDepthTile,
               (depth.cols + kDepthTile - 1) / kDepthTile);
  tiles.setTo(cv::Vec2f(2.0f, -1.0f));
  for (int y = 0; y < depth.rows; ++y) {
    const float* row = depth.ptr<float>(y);
    cv::Vec2f* t = tiles.ptr<cv::Vec2f>(y / kDepthTile);
    for (int x = 0; x < depth.cols; ++x) {
      cv::Vec2f& m = t[x / kDepthTile];
      m[0] = std::min(m[0], row[x]);
      m[1] = std::max(m[1], row[x]);
    }
  }
}

cv::Rect tiles_within(const cv::Mat2f& tiles, const cv::Rect2d& rect, double lo, double hi) {
  const cv::Rect px = cv::Rect(cv::Point(static_cast<int>(std::floor(rect.x)),
                                         static_cast<int>(std::floor(rect.y))),
                               cv::Point(static_cast<int>(std::ceil(rect.br().x)),
                                         static_cast<int>(std::ceil(rect.br().y)))) &
                      cv::Rect(0, 0, tiles.cols * kDepthTile, tiles.rows * kDepthTile);
  if (px.empty()) return {};
  cv::Rect hit;
  for (int ty = px.y / kDepthTile; ty <= (px.br().y - 1) / kDepthTile; ++ty)
    for (int tx = px.x / kDepthTile; tx <= (px.br().x - 1) / kDepthTile; ++tx) {
      const cv::Vec2f m = tiles(ty, tx);
      if (m[1] < lo || m[0] > hi) continue;
      const cv::Rect t(tx * kDepthTile, ty * kDepthTile, kDepthTile, kDepthTile);
      hit = hit.empty() ? t : (hit | t);
    }
  return hit & px;
}

}  // namespace telex::local
