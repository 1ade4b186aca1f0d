// SPDX-License-Identifier: MIT
// The body pass's CPU side: which capsules blend, the skin's exposure, and where the remote depth
// comes near a fingertip (per-tile depth ranges) so the contact shadows shade only there, and
// which capsules each screen tile of the body holds.
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

void pack_capsules(std::span<const Capsule> capsules, const glm::dvec3& p_RightEye,
                   std::vector<float>& out) {
  out.assign(capsules.size() * kCapsuleFloats, 0.0f);
  for (std::size_t i = 0; i < capsules.size(); ++i) {
    const Capsule& c = capsules[i];
    const glm::dvec3 a = c.a - p_RightEye, b = c.b - p_RightEye;
    const double ra = c.radius_m, rb = c.radius_b_m < 0.0 ? c.radius_m : c.radius_b_m;
    if (!(ra > 0.0) || !(rb > 0.0) || !std::isfinite(ra + rb + a.x + a.y + a.z + b.x + b.y + b.z))
      continue;
    float* cap = out.data() + i * kCapsuleFloats;
    const float values[kCapsuleFloats] = {
        static_cast<float>(a.x), static_cast<float>(a.y), static_cast<float>(a.z),
        static_cast<float>(ra),  static_cast<float>(b.x), static_cast<float>(b.y),
        static_cast<float>(b.z), static_cast<float>(rb),  c.bgr[2] / 255.0f,
        c.bgr[1] / 255.0f,       c.bgr[0] / 255.0f,       c.lit ? 1.0f : 0.0f};
    std::copy(std::begin(values), std::end(values), cap);
  }
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
  constexpr double n = kViewNear_m, f = kViewFar_m;
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

namespace {

// One capsule's pixels and sort key for binning.
struct Binned {
  cv::Rect px;
  double z_near;
  std::int32_t capsule;
};

// The tile at (x, y) of side `side` with the capsules of `in` (sorted nearest first) touching it;
// split in four while it holds too many.
void bin_tile(int x, int y, int side, const cv::Size& size, std::span<const Binned> in,
              std::span<const std::array<std::int32_t, kMaxBlendNeighbours>> neighbours,
              std::vector<Binned>& scratch, BodyTiles& out) {
  const cv::Rect tile = cv::Rect(x, y, side, side) & cv::Rect(cv::Point(0, 0), size);
  if (tile.empty()) return;
  const std::size_t first = scratch.size();
  for (const Binned& b : in)
    if ((b.px & tile).area() > 0) scratch.push_back(b);
  const std::size_t n = scratch.size() - first;
  if (n > static_cast<std::size_t>(kMaxTileEntries) && side > 1) {
    const std::vector<Binned> mine(scratch.begin() + static_cast<std::ptrdiff_t>(first),
                                   scratch.end());
    scratch.resize(first);
    const int half = (side + 1) / 2;
    for (const int dy : {0, half})
      for (const int dx : {0, half})
        bin_tile(x + dx, y + dy, half, size, mine, neighbours, scratch, out);
    return;
  }
  if (n > 0) {
    const std::size_t kept = std::min<std::size_t>(n, kMaxTileEntries);
    out.left_out += n - kept;
    const std::span<const Binned> list(scratch.data() + first, kept);
    out.tiles.push_back({x, y, static_cast<std::int32_t>(out.list.size()),
                         static_cast<std::int32_t>(kept) | (side << 8)});
    for (const Binned& b : list) {
      std::int32_t mask = 0;
      for (const std::int32_t j : neighbours[static_cast<std::size_t>(b.capsule)]) {
        if (j < 0) break;
        for (std::size_t e = 0; e < kept; ++e)
          if (list[e].capsule == j) mask |= static_cast<std::int32_t>(1u << e);
      }
      out.list.push_back({b.capsule, mask});
    }
  }
  scratch.resize(first);
}

}  // namespace

void bin_body_tiles(const Intrinsics& k, const glm::dvec3& p_RightEye,
                    std::span<const Capsule> capsules,
                    std::span<const std::array<std::int32_t, kMaxBlendNeighbours>> neighbours,
                    int tile_px, BodyTiles& out) {
  out.tiles.clear();
  out.list.clear();
  out.left_out = 0;
  if (tile_px < 1 || k.width <= 0 || k.height <= 0) return;
  const int cols = (k.width + tile_px - 1) / tile_px, rows = (k.height + tile_px - 1) / tile_px;
  std::vector<Binned> binned;
  for (std::size_t i = 0; i < capsules.size() && i < neighbours.size(); ++i) {
    const Capsule& c = capsules[i];
    const cv::Rect r = body_bounds_px(k, p_RightEye, capsules.subspan(i, 1), 1);
    if (r.empty()) continue;
    const double rb = c.radius_b_m < 0.0 ? c.radius_m : c.radius_b_m;
    // As the shader's test: the capsule's points are at least this far ahead along any ray.
    const double z_near =
        std::min(c.a.z, c.b.z) - p_RightEye.z - (std::max(c.radius_m, rb) * 1.875 + 5e-4);
    binned.push_back({r, z_near, static_cast<std::int32_t>(i)});
  }
  std::sort(binned.begin(), binned.end(), [](const Binned& p, const Binned& q) {
    return p.z_near < q.z_near || (p.z_near == q.z_near && p.capsule < q.capsule);
  });
  // Per tile row, the capsules reaching into it, then per tile those touching it.
  std::vector<Binned> row, scratch;
  for (int ty = 0; ty < rows; ++ty) {
    row.clear();
    const cv::Rect band(0, ty * tile_px, k.width, tile_px);
    for (const Binned& b : binned)
      if ((b.px & band).area() > 0) row.push_back(b);
    if (row.empty()) continue;
    for (int tx = 0; tx < cols; ++tx)
      bin_tile(tx * tile_px, ty * tile_px, tile_px, cv::Size(k.width, k.height), row, neighbours,
               scratch, out);
  }
}

}  // namespace telex::local
