// SPDX-License-Identifier: MIT
// Surface snapshot construction, normals from depth and the per-point queries of the haptic loop.
#include "telex/haptics/haptic_surface.h"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <stdexcept>
#include <string>

namespace telex {

namespace {

bool valid_depth(float z) { return z > 0.0f && z <= kMaxSurfaceDepthM; }

std::string size_text(int w, int h) { return std::to_string(w) + "x" + std::to_string(h); }

// Picks the derivative along one axis at a pixel: central when both neighbours continue the
// surface, otherwise the one-sided difference that does. Returns false when neither does.
bool axis_tangent(const Intrinsics& k, double z0, const glm::dvec3& p0, bool has_prev, float z_prev,
                  double u_prev, double v_prev, bool has_next, float z_next, double u_next,
                  double v_next, double tol, glm::dvec3& tangent) {
  const bool prev_ok = has_prev && valid_depth(z_prev) && std::abs(z_prev - z0) <= tol;
  const bool next_ok = has_next && valid_depth(z_next) && std::abs(z_next - z0) <= tol;
  if (prev_ok && next_ok) {
    tangent = back_project(k, u_next, v_next, z_next) - back_project(k, u_prev, v_prev, z_prev);
  } else if (next_ok) {
    tangent = back_project(k, u_next, v_next, z_next) - p0;
  } else if (prev_ok) {
    tangent = p0 - back_project(k, u_prev, v_prev, z_prev);
  } else {
    return false;
  }
  return true;
}

}  // namespace

cv::Mat3f normals_from_depth(const cv::Mat1f& depth_m, const Intrinsics& k,
                             const StepTolerance& steps, int radius_px) {
  if (radius_px < 1) throw std::invalid_argument("normals_from_depth: radius_px must be >= 1");
  const int r = radius_px;
  cv::Mat3f normals(depth_m.size(), cv::Vec3f(0.0f, 0.0f, 0.0f));
  const int w = depth_m.cols;
  const int h = depth_m.rows;
  for (int v = 0; v < h; ++v) {
    const float* row = depth_m.ptr<float>(v);
    const float* up = v >= r ? depth_m.ptr<float>(v - r) : nullptr;
    const float* down = v + r < h ? depth_m.ptr<float>(v + r) : nullptr;
    cv::Vec3f* out = normals.ptr<cv::Vec3f>(v);
    for (int u = 0; u < w; ++u) {
      const float z = row[u];
      if (!valid_depth(z)) continue;
      // Neighbours r pixels away: the larger baseline keeps millimetre quantisation from
      // tilting the normal; the tolerance grows with it so slopes still count as one surface.
      const double tol = steps.at(z) * r;
      const glm::dvec3 p0 = back_project(k, u, v, z);
      glm::dvec3 tx, ty;
      if (!axis_tangent(k, z, p0, u >= r, u >= r ? row[u - r] : 0.0f, u - r, v, u + r < w,
                        u + r < w ? row[u + r] : 0.0f, u + r, v, tol, tx))
        continue;
      if (!axis_tangent(k, z, p0, up != nullptr, up ? up[u] : 0.0f, u, v - r, down != nullptr,
                        down ? down[u] : 0.0f, u, v + r, tol, ty))
        continue;
      glm::dvec3 n = glm::cross(ty, tx);
      const double len = glm::length(n);
      if (!(len > 0.0)) continue;
      n /= len;
      if (glm::dot(n, p0) > 0.0) n = -n;
      out[u] = cv::Vec3f(static_cast<float>(n.x), static_cast<float>(n.y), static_cast<float>(n.z));
    }
  }
  return normals;
}

Surface make_surface(cv::Mat1f depth_m, const Intrinsics& intrinsics, std::int64_t capture_ns,
                     std::uint64_t frame_id, cv::Mat3f normals, const StepTolerance& steps,
                     int normal_radius_px) {
  if (depth_m.empty()) throw std::invalid_argument("make_surface: depth_m is empty");
  if (depth_m.cols != intrinsics.width || depth_m.rows != intrinsics.height)
    throw std::invalid_argument(
        "make_surface: depth_m is " + size_text(depth_m.cols, depth_m.rows) +
        " but the intrinsics describe " + size_text(intrinsics.width, intrinsics.height));
  if (!(intrinsics.fx > 0.0) || !(intrinsics.fy > 0.0))
    throw std::invalid_argument("make_surface: intrinsics fx and fy must be positive");
  if (!normals.empty() && normals.size() != depth_m.size())
    throw std::invalid_argument("make_surface: normals are " +
                                size_text(normals.cols, normals.rows) + " but depth_m is " +
                                size_text(depth_m.cols, depth_m.rows));
  // Own the pixels: the snapshot must stay immutable while the loop reads it.
  depth_m = depth_m.clone();
  for (int v = 0; v < depth_m.rows; ++v) {
    float* row = depth_m.ptr<float>(v);
    for (int u = 0; u < depth_m.cols; ++u)
      if (!(std::isfinite(row[u]) && valid_depth(row[u]))) row[u] = 0.0f;
  }
  Surface s;
  s.intrinsics = intrinsics;
  s.capture_ns = capture_ns;
  s.frame_id = frame_id;
  if (normals.empty()) {
    s.normals = normals_from_depth(depth_m, intrinsics, steps, normal_radius_px);
  } else {
    s.normals = normals.clone();
    // A normal that is not finite or not unit length would poison the force: mark it absent.
    for (int v = 0; v < s.normals.rows; ++v) {
      cv::Vec3f* row = s.normals.ptr<cv::Vec3f>(v);
      for (int u = 0; u < s.normals.cols; ++u) {
        const cv::Vec3f n = row[u];
        const float len2 = n.dot(n);
        if (!std::isfinite(len2) || std::abs(len2 - 1.0f) > 0.01f) row[u] = cv::Vec3f(0, 0, 0);
      }
    }
  }
  s.depth_m = std::move(depth_m);
  return s;
}

namespace {

struct Corners {
  int u0, v0;
  double fu, fv;
  float z[4];    // (u0,v0) (u0+1,v0) (u0,v0+1) (u0+1,v0+1)
  bool keep[4];  // on the nearer surface
  int nearest;   // index of the pixel nearest to (u, v)
  double z_min;
};

// Gathers the 2x2 neighbourhood of (u, v) and marks which pixels lie on the nearer surface.
// Returns false when the nearest pixel is a hole.
bool gather(const Surface& s, double u, double v, const StepTolerance& steps, Corners& c) {
  const int w = s.depth_m.cols;
  const int h = s.depth_m.rows;
  c.u0 = std::clamp(static_cast<int>(std::floor(u)), 0, std::max(0, w - 2));
  c.v0 = std::clamp(static_cast<int>(std::floor(v)), 0, std::max(0, h - 2));
  c.fu = std::clamp(u - c.u0, 0.0, 1.0);
  c.fv = std::clamp(v - c.v0, 0.0, 1.0);
  const int u1 = std::min(c.u0 + 1, w - 1);
  const int v1 = std::min(c.v0 + 1, h - 1);
  c.z[0] = s.depth_m(c.v0, c.u0);
  c.z[1] = s.depth_m(c.v0, u1);
  c.z[2] = s.depth_m(v1, c.u0);
  c.z[3] = s.depth_m(v1, u1);
  c.nearest = (c.fu >= 0.5 ? 1 : 0) + (c.fv >= 0.5 ? 2 : 0);
  if (!valid_depth(c.z[c.nearest])) return false;
  c.z_min = kMaxSurfaceDepthM;
  for (float z : c.z)
    if (valid_depth(z)) c.z_min = std::min<double>(c.z_min, z);
  const double tol = steps.at(c.z_min);
  for (int i = 0; i < 4; ++i) c.keep[i] = valid_depth(c.z[i]) && c.z[i] - c.z_min <= tol;
  return true;
}

double weight(const Corners& c, int i) {
  const double wu = (i & 1) ? c.fu : 1.0 - c.fu;
  const double wv = (i & 2) ? c.fv : 1.0 - c.fv;
  return wu * wv;
}

double blended_depth(const Corners& c) {
  double sum_w = 0.0, sum_z = 0.0;
  for (int i = 0; i < 4; ++i) {
    if (!c.keep[i]) continue;
    const double wi = weight(c, i);
    sum_w += wi;
    sum_z += wi * c.z[i];
  }
  // All kept weights can vanish only when (u, v) sits exactly on a dropped neighbour's corner.
  return sum_w > 1e-12 ? sum_z / sum_w : c.z_min;
}

}  // namespace

std::optional<double> depth_at(const Surface& s, double u, double v, const StepTolerance& steps) {
  if (s.depth_m.empty()) return std::nullopt;
  if (!(u >= -0.5 && v >= -0.5 && u <= s.depth_m.cols - 0.5 && v <= s.depth_m.rows - 0.5))
    return std::nullopt;
  Corners c;
  if (!gather(s, u, v, steps, c)) return std::nullopt;
  return blended_depth(c);
}

std::optional<glm::dvec3> fit_plane_normal(const Surface& s, int u, int v, double z_ref, int r,
                                           const StepTolerance& steps) {
  const double tol = steps.at(z_ref);
  // Centre on the reference point so the normal equations stay well conditioned.
  const glm::dvec3 c0 = back_project(s.intrinsics, u, v, z_ref);
  double sxx = 0, sxy = 0, syy = 0, sx = 0, sy = 0, sz = 0, sxz = 0, syz = 0;
  int n = 0;
  const int u_lo = std::max(0, u - r), u_hi = std::min(s.depth_m.cols - 1, u + r);
  const int v_lo = std::max(0, v - r), v_hi = std::min(s.depth_m.rows - 1, v + r);
  for (int y = v_lo; y <= v_hi; ++y) {
    const float* row = s.depth_m.ptr<float>(y);
    for (int x = u_lo; x <= u_hi; ++x) {
      const float z = row[x];
      if (!valid_depth(z) || std::abs(z - z_ref) > tol) continue;
      const glm::dvec3 p = back_project(s.intrinsics, x, y, z) - c0;
      sxx += p.x * p.x;
      sxy += p.x * p.y;
      syy += p.y * p.y;
      sx += p.x;
      sy += p.y;
      sz += p.z;
      sxz += p.x * p.z;
      syz += p.y * p.z;
      ++n;
    }
  }
  if (n < 3) return std::nullopt;
  // Remove the means: fit z - mz = b (x - mx) + c (y - my).
  const double mx = sx / n, my = sy / n, mz = sz / n;
  const double cxx = sxx - n * mx * mx, cxy = sxy - n * mx * my, cyy = syy - n * my * my;
  const double cxz = sxz - n * mx * mz, cyz = syz - n * my * mz;
  const double det = cxx * cyy - cxy * cxy;
  const double scale = (cxx + cyy) * (cxx + cyy);
  if (!(det > 1e-9 * scale) || !(scale > 0.0)) return std::nullopt;
  const double b = (cxz * cyy - cyz * cxy) / det;
  const double c = (cyz * cxx - cxz * cxy) / det;
  glm::dvec3 nrm = glm::normalize(glm::dvec3(b, c, -1.0));
  if (!std::isfinite(nrm.x + nrm.y + nrm.z)) return std::nullopt;
  return nrm;  // z component is negative: faces the camera
}

SurfaceQuery local_plane(const Surface& s, const glm::dvec3& p, LocalPlane& out,
                         const StepTolerance& steps) {
  if (!(p.z > 1e-6)) return SurfaceQuery::BehindCamera;
  if (s.depth_m.empty()) return SurfaceQuery::OutsideImage;
  const Intrinsics& k = s.intrinsics;
  const double u = k.fx * p.x / p.z + k.cx;
  const double v = k.fy * p.y / p.z + k.cy;
  if (!(u >= -0.5 && v >= -0.5 && u <= s.depth_m.cols - 0.5 && v <= s.depth_m.rows - 0.5))
    return SurfaceQuery::OutsideImage;
  Corners c;
  if (!gather(s, u, v, steps, c)) return SurfaceQuery::Hole;
  const double z = blended_depth(c);
  out.p_CameraQ = back_project(k, u, v, z);

  glm::dvec3 n_sum(0.0);
  const int u1 = std::min(c.u0 + 1, s.depth_m.cols - 1);
  const int v1 = std::min(c.v0 + 1, s.depth_m.rows - 1);
  const int us[4] = {c.u0, u1, c.u0, u1};
  const int vs[4] = {c.v0, c.v0, v1, v1};
  for (int i = 0; i < 4; ++i) {
    if (!c.keep[i]) continue;
    const cv::Vec3f n = s.normals(vs[i], us[i]);
    if (n[0] == 0.0f && n[1] == 0.0f && n[2] == 0.0f) continue;
    n_sum += weight(c, i) * glm::dvec3(n[0], n[1], n[2]);
  }
  const double len = glm::length(n_sum);
  if (len > 1e-9) {
    out.normal_Camera = n_sum / len;
    out.normal_fallback = false;
    return SurfaceQuery::Ok;
  }
  out.normal_fallback = true;
  const int un = (c.nearest & 1) ? u1 : c.u0;
  const int vn = (c.nearest & 2) ? v1 : c.v0;
  if (auto fit = fit_plane_normal(s, un, vn, c.z_min, 2, steps)) {
    out.normal_Camera = *fit;
  } else {
    out.normal_Camera = -glm::normalize(out.p_CameraQ);
  }
  return SurfaceQuery::Ok;
}

}  // namespace telex
