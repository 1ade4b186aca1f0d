// SPDX-License-Identifier: MIT
// False-colour views of depth and normal maps.
#include "telex/common/colorize.h"

#include <algorithm>
#include <array>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

namespace telex {
namespace {

// 1st and 99th percentile of the non-zero values, from a histogram (values are 16-bit).
std::pair<std::uint16_t, std::uint16_t> valid_range(const cv::Mat1w& depth_mm) {
  std::vector<std::uint32_t> hist(65536, 0);
  std::uint64_t n = 0;
  for (int v = 0; v < depth_mm.rows; ++v) {
    const std::uint16_t* p = depth_mm[v];
    for (int u = 0; u < depth_mm.cols; ++u)
      if (p[u]) ++hist[p[u]], ++n;
  }
  if (n == 0) return {0, 0};
  const std::uint64_t lo_rank = n / 100, hi_rank = n - 1 - n / 100;
  std::uint64_t seen = 0;
  int lo = -1, hi = -1;
  for (int d = 1; d < 65536; ++d) {
    seen += hist[d];
    if (lo < 0 && seen > lo_rank) lo = d;
    if (seen > hi_rank) {
      hi = d;
      break;
    }
  }
  return {static_cast<std::uint16_t>(lo), static_cast<std::uint16_t>(hi)};
}

}  // namespace

cv::Mat3b colorize_depth(const cv::Mat1w& depth_mm, std::uint16_t min_mm, std::uint16_t max_mm) {
  if (min_mm > max_mm) throw std::invalid_argument("colorize_depth: min_mm must not exceed max_mm");
  if (min_mm == 0 && max_mm == 0) std::tie(min_mm, max_mm) = valid_range(depth_mm);
  const double span = std::max(1, max_mm - min_mm);
  cv::Mat1b level(depth_mm.size());
  for (int v = 0; v < depth_mm.rows; ++v) {
    const std::uint16_t* d = depth_mm[v];
    std::uint8_t* l = level[v];
    for (int u = 0; u < depth_mm.cols; ++u) {
      const double t = std::clamp((max_mm - static_cast<double>(d[u])) / span, 0.0, 1.0);
      l[u] = static_cast<std::uint8_t>(t * 255.0 + 0.5);
    }
  }
  cv::Mat3b out;
  cv::applyColorMap(level, out, cv::COLORMAP_TURBO);
  out.setTo(cv::Vec3b(0, 0, 0), depth_mm == 0);
  return out;
}

cv::Mat3b colorize_normals(const cv::Mat3f& normals) {
  cv::Mat3b out(normals.size());
  for (int v = 0; v < normals.rows; ++v) {
    const cv::Vec3f* n = normals[v];
    cv::Vec3b* o = out[v];
    for (int u = 0; u < normals.cols; ++u) {
      if (n[u][0] == 0.0f && n[u][1] == 0.0f && n[u][2] == 0.0f) {
        o[u] = cv::Vec3b(0, 0, 0);
        continue;
      }
      auto c = [](float x) {
        return static_cast<std::uint8_t>(std::clamp((x + 1.0f) * 127.5f + 0.5f, 0.0f, 255.0f));
      };
      o[u] = cv::Vec3b(c(n[u][2]), c(n[u][1]), c(n[u][0]));
    }
  }
  return out;
}

}  // namespace telex
