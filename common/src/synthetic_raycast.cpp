// SPDX-License-Identifier: MIT
// Analytic ray casting of a synthetic scene: nearest hit, its normal and object id.
#include <algorithm>
#include <array>
#include <cmath>
#include <glm/geometric.hpp>
#include <opencv2/core/utility.hpp>
#include <stdexcept>

#include "synthetic_internal.h"
#include "telex/common/synthetic.h"

namespace telex::synth {

using namespace detail;

// ---- Ray casting -------------------------------------------------------------------------------

namespace {
bool in_mask(std::uint64_t mask, int id) { return id >= 64 || ((mask >> id) & 1u); }
}  // namespace

std::vector<Scene::Bound> Scene::finite_bounds() const {
  std::vector<Bound> out;
  for (const Sphere& s : spheres_)
    out.push_back({box_corners(s.c, {s.r, 0, 0}, {0, s.r, 0}, {0, 0, s.r}), s.id});
  for (const Box& b : boxes_)
    out.push_back({box_corners(b.c, b.rot[0] * b.h.x, b.rot[1] * b.h.y, b.rot[2] * b.h.z), b.id});
  for (const Cylinder& c : cylinders_) {
    // Any two unit vectors perpendicular to the axis complete the enclosing box.
    const glm::dvec3 helper = std::abs(c.axis.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
    const glm::dvec3 e0 = glm::normalize(glm::cross(c.axis, helper));
    const glm::dvec3 e1 = glm::cross(c.axis, e0);
    out.push_back({box_corners(c.c, e0 * c.r, e1 * c.r, c.axis * c.half_h), c.id});
  }
  return out;
}

std::optional<Hit> Scene::raycast(const glm::dvec3& o, const glm::dvec3& d) const {
  Hit hit;
  if (!cast_masked(o, d, ~std::uint64_t{0}, hit)) return std::nullopt;
  return hit;
}

bool Scene::blocked(const glm::dvec3& o, const glm::dvec3& d, double max_t_m,
                    int skip_object) const {
  return blocked_masked(o, d, max_t_m, skip_object, ~std::uint64_t{0});
}

bool Scene::cast_masked(const glm::dvec3& o, const glm::dvec3& d, std::uint64_t mask,
                        Hit& hit) const {
  double best = 1e300;
  int kind = -1, index = -1;
  for (std::size_t i = 0; i < planes_.size(); ++i) {
    const Plane& p = planes_[i];
    const double denom = glm::dot(p.n, d);
    if (std::abs(denom) < 1e-15) continue;
    const double t = (p.d - glm::dot(p.n, o)) / denom;
    if (t > kTMin && t < best) best = t, kind = 0, index = static_cast<int>(i);
  }
  for (std::size_t i = 0; i < spheres_.size(); ++i) {
    if (!in_mask(mask, spheres_[i].id)) continue;
    const double t = hit_sphere(spheres_[i].c, spheres_[i].r, o, d, best);
    if (t > 0) best = t, kind = 1, index = static_cast<int>(i);
  }
  for (std::size_t i = 0; i < boxes_.size(); ++i) {
    const Box& b = boxes_[i];
    if (!in_mask(mask, b.id)) continue;
    const double t = hit_box(b.c, b.h, b.rot, b.bound_r, o, d, best);
    if (t > 0) best = t, kind = 2, index = static_cast<int>(i);
  }
  for (std::size_t i = 0; i < cylinders_.size(); ++i) {
    const Cylinder& c = cylinders_[i];
    if (!in_mask(mask, c.id)) continue;
    const double t = hit_cylinder(c.c, c.axis, c.r, c.half_h, c.bound_r, o, d, best);
    if (t > 0) best = t, kind = 3, index = static_cast<int>(i);
  }
  if (kind < 0) return false;

  hit.t_m = best;
  hit.p_CameraHit = o + best * d;
  switch (kind) {
    case 0: {
      const Plane& p = planes_[index];
      hit.normal_camera = glm::dot(p.n, d) < 0 ? p.n : -p.n;  // planes face the viewer
      hit.object_id = p.id;
      break;
    }
    case 1: {
      const Sphere& s = spheres_[index];
      hit.normal_camera = (hit.p_CameraHit - s.c) / s.r;
      hit.object_id = s.id;
      break;
    }
    case 2: {
      const Box& b = boxes_[index];
      const glm::dvec3 q = to_local(b.rot, hit.p_CameraHit - b.c);
      int axis = 0;
      double most = -1;
      for (int i = 0; i < 3; ++i) {
        const double f = std::abs(q[i]) / b.h[i];
        if (f > most) most = f, axis = i;
      }
      hit.normal_camera = b.rot[axis] * (q[axis] < 0 ? -1.0 : 1.0);
      hit.object_id = b.id;
      break;
    }
    default: {
      const Cylinder& c = cylinders_[index];
      const glm::dvec3 q = hit.p_CameraHit - c.c;
      const double qa = glm::dot(q, c.axis);
      const glm::dvec3 radial = q - qa * c.axis;
      // The face the hit lies closest to, in units of each face's extent.
      if (std::abs(std::abs(qa) - c.half_h) < std::abs(glm::length(radial) - c.r))
        hit.normal_camera = c.axis * (qa < 0 ? -1.0 : 1.0);
      else
        hit.normal_camera = radial / glm::length(radial);
      hit.object_id = c.id;
      break;
    }
  }
  return true;
}

bool Scene::blocked_masked(const glm::dvec3& o, const glm::dvec3& d, double max_t_m,
                           int skip_object, std::uint64_t mask) const {
  constexpr double kEps = 1e-6;
  auto in_range = [&](double t) { return t > kEps && t < max_t_m; };
  for (const Plane& p : planes_) {
    if (p.id == skip_object) continue;
    // kEps < num / denom < max_t_m without dividing: shadow rays are cast per pixel.
    double denom = glm::dot(p.n, d), num = p.d - glm::dot(p.n, o);
    if (denom < 0) denom = -denom, num = -num;
    if (denom < 1e-15) continue;
    if (num > kEps * denom && num < max_t_m * denom) return true;
  }
  for (const Sphere& s : spheres_)
    if (s.id != skip_object && in_mask(mask, s.id) && in_range(hit_sphere(s.c, s.r, o, d, max_t_m)))
      return true;
  for (const Box& b : boxes_)
    if (b.id != skip_object && in_mask(mask, b.id) &&
        in_range(hit_box(b.c, b.h, b.rot, b.bound_r, o, d, max_t_m)))
      return true;
  for (const Cylinder& c : cylinders_)
    if (c.id != skip_object && in_mask(mask, c.id) &&
        in_range(hit_cylinder(c.c, c.axis, c.r, c.half_h, c.bound_r, o, d, max_t_m)))
      return true;
  return false;
}

}  // namespace telex::synth
