// SPDX-License-Identifier: MIT
// Depth-to-target-camera registration kernels: shift+scale resampling and z-buffered reprojection.
#include "telex/common/registration.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

namespace telex {
namespace {

void check_inputs(const DepthImage& depth, const Intrinsics& target, const char* who) {
  if (depth.depth_mm.empty()) throw std::invalid_argument(std::string(who) + ": empty depth image");
  if (target.width <= 0 || target.height <= 0 || !(target.fx > 0) || !(target.fy > 0))
    throw std::invalid_argument(std::string(who) +
                                ": target intrinsics need width, height, fx, fy > 0");
  if (!(depth.intrinsics.fx > 0) || !(depth.intrinsics.fy > 0))
    throw std::invalid_argument(std::string(who) + ": depth intrinsics need fx, fy > 0");
}

// Keeps the nearer of an existing value and a new one (0 = empty).
inline void keep_nearest(std::uint16_t& dst, std::uint16_t z) {
  if (dst == kNoDepth || z < dst) dst = z;
}

// floor(t) for t within int's range, without a call to libm's floor per pixel (x86-64's baseline
// has no rounding instruction): the truncation, one less where it rounded a negative t up.
template <typename T>
inline int floor_int(T t) {
  const int i = static_cast<int>(t);
  return i - (t < static_cast<T>(i));
}

// Target pixel range [first, last) whose centres fall inside [lo, hi), clipped to [0, n). A
// footprint narrower than a pixel that holds no centre still lands on the pixel nearest its
// middle, so when minifying every source pixel competes (nearest wins) and thin objects survive.
inline void centre_range(double lo, double hi, int n, int& first, int& last) {
  first = static_cast<int>(std::ceil(lo));
  last = static_cast<int>(std::ceil(hi));
  if (first >= last) {
    first = static_cast<int>(std::floor(0.5 * (lo + hi) + 0.5));
    last = first + 1;
  }
  first = std::max(0, first);
  last = std::min(n, last);
}

}  // namespace

ShiftScale shift_scale_from_calibration(const Intrinsics& depth, const Intrinsics& target,
                                        const glm::dvec3& t, double nominal_depth_m) {
  if (!(nominal_depth_m > 0.0))
    throw std::invalid_argument("shift_scale_from_calibration: nominal_depth_m must be > 0");
  ShiftScale p;
  p.scale_x = target.fx / depth.fx;
  p.scale_y = target.fy / depth.fy;
  // u' = fx' (X + t_x) / (Z + t_z) + cx' with X = (u - cx) Z / fx is, at Z = Z0, exactly the
  // affine map below; any other Z shifts by fx' t_x (1 / (Z + t_z) - 1 / (Z0 + t_z)).
  const double z_target = nominal_depth_m + t.z;
  p.scale_x *= nominal_depth_m / z_target;
  p.scale_y *= nominal_depth_m / z_target;
  p.shift_x_px = target.fx * t.x / z_target;
  p.shift_y_px = target.fy * t.y / z_target;
  p.depth_offset_mm = static_cast<int>(std::lround(t.z * 1000.0));
  return p;
}

DepthImage register_shift_scale(const DepthImage& depth, const ShiftScale& p,
                                const Intrinsics& target) {
  check_inputs(depth, target, "register_shift_scale");
  if (!(p.scale_x > 0.0) || !(p.scale_y > 0.0))
    throw std::invalid_argument("register_shift_scale: scale_x and scale_y must be > 0");
  const Intrinsics& k = depth.intrinsics;
  const int w = depth.width(), h = depth.height();
  // The map is separable, so each source column / row has one target range.
  std::vector<int> col_first(w), col_last(w), row_first(h), row_last(h);
  for (int u = 0; u < w; ++u) {
    const double lo = (u - 0.5 - k.cx) * p.scale_x + target.cx + p.shift_x_px;
    centre_range(lo, lo + p.scale_x, target.width, col_first[u], col_last[u]);
  }
  for (int v = 0; v < h; ++v) {
    const double lo = (v - 0.5 - k.cy) * p.scale_y + target.cy + p.shift_y_px;
    centre_range(lo, lo + p.scale_y, target.height, row_first[v], row_last[v]);
  }
  DepthImage out;
  out.intrinsics = target;
  out.depth_mm = cv::Mat1w(target.height, target.width, kNoDepth);
  for (int v = 0; v < h; ++v) {
    if (row_first[v] >= row_last[v]) continue;
    const std::uint16_t* src = depth.depth_mm[v];
    for (int u = 0; u < w; ++u) {
      if (src[u] == kNoDepth || col_first[u] >= col_last[u]) continue;
      const int z = src[u] + p.depth_offset_mm;
      if (z <= 0 || z > 65535) continue;
      for (int tv = row_first[v]; tv < row_last[v]; ++tv) {
        std::uint16_t* dst = out.depth_mm[tv];
        for (int tu = col_first[u]; tu < col_last[u]; ++tu)
          keep_nearest(dst[tu], static_cast<std::uint16_t>(z));
      }
    }
  }
  return out;
}

DepthImage reproject_depth(const DepthImage& depth, const Intrinsics& target,
                           const RigidTransform& x, bool fill_cracks) {
  check_inputs(depth, target, "reproject_depth");
  const Intrinsics& k = depth.intrinsics;
  const int w = depth.width(), h = depth.height();
  DepthImage out;
  out.intrinsics = target;
  out.depth_mm = cv::Mat1w(target.height, target.width, kNoDepth);
  // The splats go to a separate buffer, in the same pass, so they never overwrite a direct hit.
  cv::Mat1w splat;
  if (fill_cracks) splat = cv::Mat1w(target.height, target.width, kNoDepth);

  std::vector<double> xn(w);
  for (int u = 0; u < w; ++u) xn[u] = (u - k.cx) / k.fx;
  for (int v = 0; v < h; ++v) {
    const std::uint16_t* src = depth.depth_mm[v];
    const double yn = (v - k.cy) / k.fy;
    for (int u = 0; u < w; ++u) {
      if (src[u] == kNoDepth) continue;
      const double z = src[u] * 1e-3;
      const glm::dvec3 q = x.rotation * glm::dvec3(xn[u] * z, yn * z, z) + x.translation_m;
      if (!(q.z > 0.0)) continue;
      const double zmm = q.z * 1000.0 + 0.5;
      if (zmm >= 65536.0 || zmm < 1.0) continue;
      const std::uint16_t z_mm = static_cast<std::uint16_t>(zmm);
      const double inv_z = 1.0 / q.z;
      const double tu = target.fx * q.x * inv_z + target.cx;
      const double tv = target.fy * q.y * inv_z + target.cy;
      // Nearest pixel; the range test keeps the int conversions defined.
      if (!(tu > -1.0 && tv > -1.0 && tu < target.width + 1.0 && tv < target.height + 1.0))
        continue;
      const int iu = floor_int(tu + 0.5);
      const int iv = floor_int(tv + 0.5);
      if (iu >= 0 && iv >= 0 && iu < target.width && iv < target.height)
        keep_nearest(out.depth_mm(iv, iu), z_mm);
      if (!fill_cracks) continue;
      // The 2x2 splat: the four pixels around the projected position.
      const int u0 = floor_int(static_cast<float>(tu));
      const int v0 = floor_int(static_cast<float>(tv));
      for (int sv = std::max(v0, 0); sv < std::min(v0 + 2, target.height); ++sv) {
        std::uint16_t* row = splat[sv];
        for (int su = std::max(u0, 0); su < std::min(u0 + 2, target.width); ++su)
          keep_nearest(row[su], z_mm);
      }
    }
  }
  if (!fill_cracks) return out;
  for (int v = 0; v < target.height; ++v) {
    std::uint16_t* d = out.depth_mm[v];
    const std::uint16_t* s = splat[v];
    for (int u = 0; u < target.width; ++u)
      if (d[u] == kNoDepth) d[u] = s[u];
  }
  return out;
}

void shift_depth_along_rows(const cv::Mat1w& depth_mm, double fx, double shift_m, cv::Mat1w& out) {
  if (!(fx > 0.0)) throw std::invalid_argument("shift_depth_along_rows: fx must be > 0");
  const int w = depth_mm.cols;
  out.create(depth_mm.size());
  const double f_t_mm = fx * shift_m * 1000.0;  // the shift in px is f_t_mm / z_mm
  // One row's nearest hits and splats, "none" as the largest depth so that the nearest is a
  // plain min (no branch per pixel), one pixel of margin each side for the pixels that land
  // just outside the row (index = column + 1).
  constexpr std::uint16_t kNone = 0xFFFF;
  std::vector<std::uint16_t> hit(static_cast<std::size_t>(w) + 2), splat(hit.size());
  for (int v = 0; v < depth_mm.rows; ++v) {
    const std::uint16_t* src = depth_mm[v];
    std::fill(hit.begin(), hit.end(), kNone);
    std::fill(splat.begin(), splat.end(), kNone);
    for (int u = 0; u < w; ++u) {
      const std::uint16_t z = src[u];
      if (z == kNoDepth) continue;
      const double tu = u + f_t_mm / z;
      if (!(tu > -1.0 && tu < w)) continue;  // lands nowhere in the row (and the ints stay defined)
      const auto at = [](std::vector<std::uint16_t>& row, int column) -> std::uint16_t& {
        return row[static_cast<std::size_t>(column + 1)];
      };
      std::uint16_t& h = at(hit, floor_int(tu + 0.5));  // -1 .. w
      h = std::min(h, z);
      const int u0 = floor_int(tu);  // -1 .. w - 1
      at(splat, u0) = std::min(at(splat, u0), z);
      at(splat, u0 + 1) = std::min(at(splat, u0 + 1), z);
    }
    std::uint16_t* dst = out[v];
    for (int u = 0; u < w; ++u) {
      const std::uint16_t h = hit[static_cast<std::size_t>(u + 1)];
      const std::uint16_t d = h != kNone ? h : splat[static_cast<std::size_t>(u + 1)];
      dst[u] = d == kNone ? kNoDepth : d;
    }
  }
}

std::size_t fill_disocclusions(cv::Mat1w& depth_mm, double fx, double baseline_m, double slack_px) {
  if (!(fx > 0.0)) throw std::invalid_argument("fill_disocclusions: fx must be > 0");
  const double f_b_mm = fx * std::abs(baseline_m) * 1000.0;  // parallax px = f_b_mm / z_mm
  std::size_t filled = 0;
  for (int v = 0; v < depth_mm.rows; ++v) {
    std::uint16_t* row = depth_mm[v];
    const int w = depth_mm.cols;
    for (int u = 0; u < w;) {
      if (row[u] != kNoDepth) {
        ++u;
        continue;
      }
      int end = u;
      while (end < w && row[end] == kNoDepth) ++end;
      const std::uint16_t before = u > 0 ? row[u - 1] : kNoDepth;
      const std::uint16_t after = end < w ? row[end] : kNoDepth;
      double widest = -1.0;
      std::uint16_t fill = kNoDepth;
      if (before != kNoDepth && after != kNoDepth) {
        const double z_near = std::min(before, after), z_far = std::max(before, after);
        widest = f_b_mm * (1.0 / z_near - 1.0 / z_far);
        fill = std::max(before, after);
      } else if (before != kNoDepth || after != kNoDepth) {
        fill = before != kNoDepth ? before : after;
        widest = f_b_mm / fill;
      }
      if (fill != kNoDepth && end - u <= widest + slack_px) {
        std::fill(row + u, row + end, fill);
        filled += static_cast<std::size_t>(end - u);
      }
      u = end;
    }
  }
  return filled;
}

}  // namespace telex
