// SPDX-License-Identifier: MIT
// What the synthetic renderer's parts share: rotations, ray-primitive intersections, the per-pixel
// random numbers and lookup tables, pixel bounds of objects. Internal to
// common/src/synthetic_*.cpp.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <glm/geometric.hpp>
#include <numbers>
#include <optional>

#include "telex/common/synthetic.h"

namespace telex::synth::detail {

constexpr double kTMin = 1e-9;
constexpr double kPi = std::numbers::pi;

inline double deg(double d) { return d * kPi / 180.0; }

// Camera pitched down by `a` rad: p_CameraHit = R * p_WorldQ, world y down, z forward and level.
inline glm::dmat3 pitch_down(double a) {
  glm::dmat3 r(1.0);
  const double c = std::cos(a), s = std::sin(a);
  r[1][1] = c;
  r[2][1] = -s;
  r[1][2] = s;
  r[2][2] = c;
  return r;
}

inline glm::dmat3 yaw(double a) {
  glm::dmat3 r(1.0);
  const double c = std::cos(a), s = std::sin(a);
  r[0][0] = c;
  r[2][0] = s;
  r[0][2] = -s;
  r[2][2] = c;
  return r;
}

// Column i of a glm matrix is axis i of the box frame expressed in the camera frame.
inline glm::dvec3 to_local(const glm::dmat3& rot, const glm::dvec3& v) {
  return {glm::dot(rot[0], v), glm::dot(rot[1], v), glm::dot(rot[2], v)};
}

// Rejects a ray whose bounding-sphere interval cannot contain a hit in (t_min, t_max).
inline bool bound_misses(const glm::dvec3& oc, const glm::dvec3& d, double r, double t_max) {
  const double b = glm::dot(oc, d);
  const double c = glm::dot(oc, oc) - r * r;
  if (-b - r > t_max) return true;
  if (b > r && c > 0.0) return true;  // centre behind the origin and origin outside
  return b * b - c < 0.0;
}

inline double hit_sphere(const glm::dvec3& c, double r, const glm::dvec3& o, const glm::dvec3& d,
                         double t_max) {
  const glm::dvec3 oc = o - c;
  const double b = glm::dot(oc, d);
  if (-b - r > t_max) return -1.0;
  const double disc = b * b - (glm::dot(oc, oc) - r * r);
  if (disc < 0.0) return -1.0;
  const double s = std::sqrt(disc);
  double t = -b - s;
  if (t <= kTMin) t = -b + s;
  return (t > kTMin && t < t_max) ? t : -1.0;
}

inline double hit_box(const glm::dvec3& c, const glm::dvec3& h, const glm::dmat3& rot,
                      double bound_r, const glm::dvec3& o, const glm::dvec3& d, double t_max) {
  const glm::dvec3 oc = o - c;
  if (bound_misses(oc, d, bound_r, t_max)) return -1.0;
  const glm::dvec3 ob = to_local(rot, oc);
  const glm::dvec3 db = to_local(rot, d);
  double t_near = -1e300, t_far = 1e300;
  for (int i = 0; i < 3; ++i) {
    if (std::abs(db[i]) < 1e-15) {
      if (std::abs(ob[i]) > h[i]) return -1.0;
      continue;
    }
    const double inv = 1.0 / db[i];
    double t1 = (-h[i] - ob[i]) * inv, t2 = (h[i] - ob[i]) * inv;
    if (t1 > t2) std::swap(t1, t2);
    t_near = std::max(t_near, t1);
    t_far = std::min(t_far, t2);
    if (t_near > t_far) return -1.0;
  }
  const double t = t_near > kTMin ? t_near : t_far;
  return (t > kTMin && t < t_max) ? t : -1.0;
}

inline double hit_cylinder(const glm::dvec3& c, const glm::dvec3& a, double r, double hh,
                           double bound_r, const glm::dvec3& o, const glm::dvec3& d, double t_max) {
  const glm::dvec3 oc = o - c;
  if (bound_misses(oc, d, bound_r, t_max)) return -1.0;
  const double oa = glm::dot(oc, a), da = glm::dot(d, a);
  const glm::dvec3 op = oc - oa * a, dp = d - da * a;
  double best = t_max;
  bool found = false;
  const double qa = glm::dot(dp, dp);
  if (qa > 1e-15) {
    const double qb = glm::dot(op, dp), qc = glm::dot(op, op) - r * r;
    const double disc = qb * qb - qa * qc;
    if (disc >= 0.0) {
      const double s = std::sqrt(disc);
      for (double t : {(-qb - s) / qa, (-qb + s) / qa}) {
        if (t > kTMin && t < best && std::abs(oa + t * da) <= hh) {
          best = t;
          found = true;
          break;
        }
      }
    }
  }
  if (std::abs(da) > 1e-15) {
    for (double sgn : {-1.0, 1.0}) {
      const double t = (sgn * hh - oa) / da;
      if (t > kTMin && t < best) {
        const glm::dvec3 q = op + t * dp;
        if (glm::dot(q, q) <= r * r) {
          best = t;
          found = true;
        }
      }
    }
  }
  return found ? best : -1.0;
}

// ---- random numbers: a counter-based hash per pixel, so frames are reproducible and any pixel's
// noise is independent of how the image is traversed.
inline std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

// Standard normal quantiles at (i + 0.5) / 65536: one 16-bit slice of a hash gives one Gaussian
// sample (tails truncated at 4.3 sigma), which is several times cheaper than Box-Muller.
inline const std::array<float, 65536>& normal_table() {
  static const std::array<float, 65536> table = [] {
    std::array<float, 65536> t{};
    constexpr int kN = 65536;
    double x = -5.0;
    for (int i = 0; i < kN / 2; ++i) {
      const double p = (i + 0.5) / kN;
      for (int it = 0; it < 100; ++it) {
        const double cdf = 0.5 * std::erfc(-x / std::numbers::sqrt2);
        const double pdf = std::exp(-0.5 * x * x) / std::sqrt(2.0 * kPi);
        const double step = (cdf - p) / pdf;
        x -= step;
        if (std::abs(step) < 1e-12) break;
      }
      t[i] = static_cast<float>(x);
      t[kN - 1 - i] = static_cast<float>(-x);
    }
    return t;
  }();
  return table;
}

// Incidence angle from its cosine by table: acos per pixel cost more than the ray cast itself,
// and the noise model needs the angle only to ~1e-3 rad (worst near 0 deg, where sigma is flat).
inline double theta_from_cos(double c) {
  constexpr int kN = 4096;
  static const std::array<float, kN + 2> table = [] {
    std::array<float, kN + 2> t{};
    for (int i = 0; i <= kN; ++i) t[i] = static_cast<float>(std::acos(static_cast<double>(i) / kN));
    t[kN + 1] = 0.0f;
    return t;
  }();
  const double x = std::clamp(c, 0.0, 1.0) * kN;
  const int i = static_cast<int>(x);
  const double f = x - i;
  return table[i] + f * (table[i + 1] - table[i]);
}

// lateral_sigma_px by table over [0, pi/2] rad: it divides, and is needed for every pixel.
inline double lateral_sigma_table(double theta_rad) {
  constexpr int kN = 2048;
  static const std::array<float, kN + 2> table = [] {
    std::array<float, kN + 2> t{};
    for (int i = 0; i <= kN + 1; ++i)
      t[i] = static_cast<float>(lateral_sigma_px(i * (kPi / 2) / kN));
    return t;
  }();
  const double x = std::clamp(theta_rad, 0.0, kPi / 2) * (kN / (kPi / 2));
  const int i = static_cast<int>(x);
  return table[i] + (x - i) * (table[i + 1] - table[i]);
}

// Depth of each integer Kinect disparity, so quantising costs one division instead of two.
inline const std::array<double, 1092>& raw_depth_table() {
  static const std::array<double, 1092> table = [] {
    std::array<double, 1092> t{};
    for (int i = 0; i < 1092; ++i) t[i] = kinect_raw_to_depth_m(i);
    return t;
  }();
  return table;
}

struct PixelRect {
  double u0, u1, v0, v1;
};
// Pixel rectangle holding the image of the convex hull of `corners` (relative to the viewpoint),
// with one pixel of margin; nullopt when a corner is not in front (then always test the object).
inline std::optional<PixelRect> project_bound(const std::array<glm::dvec3, 8>& corners,
                                              const glm::dvec3& viewpoint, const Intrinsics& k) {
  double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
  for (const glm::dvec3& c : corners) {
    const glm::dvec3 p = c - viewpoint;
    if (p.z <= 1e-3) return std::nullopt;
    const double x = p.x / p.z, y = p.y / p.z;
    x0 = std::min(x0, x), x1 = std::max(x1, x), y0 = std::min(y0, y), y1 = std::max(y1, y);
  }
  return PixelRect{k.fx * x0 + k.cx - 1, k.fx * x1 + k.cx + 1, k.fy * y0 + k.cy - 1,
                   k.fy * y1 + k.cy + 1};
}

// Corners of the box centre +- sum of +-half_axes[i].
inline std::array<glm::dvec3, 8> box_corners(const glm::dvec3& c, const glm::dvec3& a0,
                                             const glm::dvec3& a1, const glm::dvec3& a2) {
  std::array<glm::dvec3, 8> out;
  for (int i = 0; i < 8; ++i)
    out[i] = c + ((i & 1) ? a0 : -a0) + ((i & 2) ? a1 : -a1) + ((i & 4) ? a2 : -a2);
  return out;
}

}  // namespace telex::synth::detail
