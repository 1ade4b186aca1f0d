// SPDX-License-Identifier: MIT
// Analytic ray casting of synthetic scenes and the Kinect-v1-like sensor model applied to it.
#include "telex/common/synthetic.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <glm/geometric.hpp>
#include <numbers>
#include <opencv2/core/utility.hpp>
#include <stdexcept>

namespace telex::synth {
namespace {

constexpr double kTMin = 1e-9;
constexpr double kPi = std::numbers::pi;

double deg(double d) { return d * kPi / 180.0; }

// Camera pitched down by `a` rad: p_camera = R * p_world, world y down, z forward and level.
glm::dmat3 pitch_down(double a) {
  glm::dmat3 r(1.0);
  const double c = std::cos(a), s = std::sin(a);
  r[1][1] = c;
  r[2][1] = -s;
  r[1][2] = s;
  r[2][2] = c;
  return r;
}

glm::dmat3 yaw(double a) {
  glm::dmat3 r(1.0);
  const double c = std::cos(a), s = std::sin(a);
  r[0][0] = c;
  r[2][0] = s;
  r[0][2] = -s;
  r[2][2] = c;
  return r;
}

// Column i of a glm matrix is axis i of the box frame expressed in the camera frame.
glm::dvec3 to_local(const glm::dmat3& rot, const glm::dvec3& v) {
  return {glm::dot(rot[0], v), glm::dot(rot[1], v), glm::dot(rot[2], v)};
}

// Rejects a ray whose bounding-sphere interval cannot contain a hit in (t_min, t_max).
bool bound_misses(const glm::dvec3& oc, const glm::dvec3& d, double r, double t_max) {
  const double b = glm::dot(oc, d);
  const double c = glm::dot(oc, oc) - r * r;
  if (-b - r > t_max) return true;
  if (b > r && c > 0.0) return true;  // centre behind the origin and origin outside
  return b * b - c < 0.0;
}

double hit_sphere(const glm::dvec3& c, double r, const glm::dvec3& o, const glm::dvec3& d,
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

double hit_box(const glm::dvec3& c, const glm::dvec3& h, const glm::dmat3& rot, double bound_r,
               const glm::dvec3& o, const glm::dvec3& d, double t_max) {
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

double hit_cylinder(const glm::dvec3& c, const glm::dvec3& a, double r, double hh, double bound_r,
                    const glm::dvec3& o, const glm::dvec3& d, double t_max) {
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
std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

// Standard normal quantiles at (i + 0.5) / 65536: one 16-bit slice of a hash gives one Gaussian
// sample (tails truncated at 4.3 sigma), which is several times cheaper than Box-Muller.
const std::array<float, 65536>& normal_table() {
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
double theta_from_cos(double c) {
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
double lateral_sigma_table(double theta_rad) {
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
const std::array<double, 1092>& raw_depth_table() {
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
std::optional<PixelRect> project_bound(const std::array<glm::dvec3, 8>& corners,
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
std::array<glm::dvec3, 8> box_corners(const glm::dvec3& c, const glm::dvec3& a0,
                                      const glm::dvec3& a1, const glm::dvec3& a2) {
  std::array<glm::dvec3, 8> out;
  for (int i = 0; i < 8; ++i)
    out[i] = c + ((i & 1) ? a0 : -a0) + ((i & 2) ? a1 : -a1) + ((i & 4) ? a2 : -a2);
  return out;
}

}  // namespace

// ---- Scene builders ----------------------------------------------------------------------------

int Scene::add_plane(const glm::dvec3& normal, double offset_m) {
  const double len = glm::length(normal);
  if (!(len > 0.0)) throw std::invalid_argument("Scene::add_plane: zero normal");
  planes_.push_back({normal / len, offset_m / len, next_id_});
  return next_id_++;
}

int Scene::add_sphere(const glm::dvec3& centre_m, double radius_m) {
  if (!(radius_m > 0.0)) throw std::invalid_argument("Scene::add_sphere: radius must be > 0");
  spheres_.push_back({centre_m, centre_m, radius_m, next_id_});
  return next_id_++;
}

int Scene::add_box(const glm::dvec3& centre_m, const glm::dvec3& half_extent_m,
                   const glm::dmat3& rotation) {
  if (!(half_extent_m.x > 0 && half_extent_m.y > 0 && half_extent_m.z > 0))
    throw std::invalid_argument("Scene::add_box: half extents must be > 0");
  boxes_.push_back({centre_m, centre_m, half_extent_m, rotation,
                    glm::length(half_extent_m) * (1 + 1e-9), next_id_});
  return next_id_++;
}

int Scene::add_cylinder(const glm::dvec3& centre_m, const glm::dvec3& axis_unit, double radius_m,
                        double half_height_m) {
  const double len = glm::length(axis_unit);
  if (!(len > 0.0) || !(radius_m > 0.0) || !(half_height_m > 0.0))
    throw std::invalid_argument("Scene::add_cylinder: axis, radius and half height must be > 0");
  const double bound = std::sqrt(radius_m * radius_m + half_height_m * half_height_m) * (1 + 1e-9);
  cylinders_.push_back(
      {centre_m, centre_m, axis_unit / len, radius_m, half_height_m, bound, next_id_});
  return next_id_++;
}

void Scene::set_motion(int object_id, const Motion& motion) {
  const bool movable =
      std::any_of(spheres_.begin(), spheres_.end(), [&](auto& s) { return s.id == object_id; }) ||
      std::any_of(boxes_.begin(), boxes_.end(), [&](auto& s) { return s.id == object_id; }) ||
      std::any_of(cylinders_.begin(), cylinders_.end(), [&](auto& s) { return s.id == object_id; });
  if (!movable)
    throw std::invalid_argument("Scene::set_motion: object " + std::to_string(object_id) +
                                " is not a sphere, box or cylinder of this scene");
  if (!(motion.period_s > 0.0))
    throw std::invalid_argument("Scene::set_motion: period_s must be > 0");
  motions_.push_back({object_id, motion});
  apply_time(time_s_);
}

const Motion* Scene::motion_of(int id) const {
  for (const auto& m : motions_)
    if (m.id == id) return &m.motion;
  return nullptr;
}

void Scene::apply_time(double t_s) {
  time_s_ = t_s;
  auto offset = [&](int id) {
    const Motion* m = motion_of(id);
    if (!m) return glm::dvec3(0.0);
    return m->amplitude_m * std::sin(2.0 * kPi * t_s / m->period_s);
  };
  for (auto& s : spheres_) s.c = s.c0 + offset(s.id);
  for (auto& b : boxes_) b.c = b.c0 + offset(b.id);
  for (auto& c : cylinders_) c.c = c.c0 + offset(c.id);
}

Scene Scene::at_time(double t_s) const {
  Scene out = *this;
  out.apply_time(t_s);
  return out;
}

bool Scene::animated() const { return !motions_.empty(); }

std::optional<std::vector<int>> Scene::moved_since(const Scene& before) const {
  if (next_id_ != before.next_id_ || planes_.size() != before.planes_.size() ||
      spheres_.size() != before.spheres_.size() || boxes_.size() != before.boxes_.size() ||
      cylinders_.size() != before.cylinders_.size())
    return std::nullopt;
  for (std::size_t i = 0; i < planes_.size(); ++i) {
    const Plane &a = planes_[i], &b = before.planes_[i];
    if (a.id != b.id || a.n != b.n || a.d != b.d) return std::nullopt;
  }
  std::vector<int> moved;
  for (std::size_t i = 0; i < spheres_.size(); ++i) {
    const Sphere &a = spheres_[i], &b = before.spheres_[i];
    if (a.id != b.id || a.c0 != b.c0 || a.r != b.r) return std::nullopt;
    if (a.c != b.c) moved.push_back(a.id);
  }
  for (std::size_t i = 0; i < boxes_.size(); ++i) {
    const Box &a = boxes_[i], &b = before.boxes_[i];
    if (a.id != b.id || a.c0 != b.c0 || a.h != b.h || a.rot != b.rot) return std::nullopt;
    if (a.c != b.c) moved.push_back(a.id);
  }
  for (std::size_t i = 0; i < cylinders_.size(); ++i) {
    const Cylinder &a = cylinders_[i], &b = before.cylinders_[i];
    if (a.id != b.id || a.c0 != b.c0 || a.axis != b.axis || a.r != b.r || a.half_h != b.half_h)
      return std::nullopt;
    if (a.c != b.c) moved.push_back(a.id);
  }
  return moved;
}

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
  hit.p_camera = o + best * d;
  switch (kind) {
    case 0: {
      const Plane& p = planes_[index];
      hit.normal_camera = glm::dot(p.n, d) < 0 ? p.n : -p.n;  // planes face the viewer
      hit.object_id = p.id;
      break;
    }
    case 1: {
      const Sphere& s = spheres_[index];
      hit.normal_camera = (hit.p_camera - s.c) / s.r;
      hit.object_id = s.id;
      break;
    }
    case 2: {
      const Box& b = boxes_[index];
      const glm::dvec3 q = to_local(b.rot, hit.p_camera - b.c);
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
      const glm::dvec3 q = hit.p_camera - c.c;
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

// ---- Named scenes ------------------------------------------------------------------------------

namespace {

// A room seen by a camera pitched down: everything is laid out in a level world frame
// (y down, z forward, origin at the camera) and rotated into the camera frame.
struct Room {
  Scene& scene;
  glm::dmat3 r;  // world -> camera
  int plane(const glm::dvec3& n_w, const glm::dvec3& p_w) {
    const glm::dvec3 n = r * n_w;
    return scene.add_plane(n, glm::dot(n, r * p_w));
  }
  int box(const glm::dvec3& c_w, const glm::dvec3& h, double yaw_rad = 0.0) {
    return scene.add_box(r * c_w, h, r * yaw(yaw_rad));
  }
  int cylinder(const glm::dvec3& c_w, const glm::dvec3& a_w, double radius, double hh) {
    return scene.add_cylinder(r * c_w, r * a_w, radius, hh);
  }
  int sphere(const glm::dvec3& c_w, double radius) { return scene.add_sphere(r * c_w, radius); }
};

constexpr double kDeskFloorY = 1.0;  // camera 1.0 m above the floor
constexpr double kDeskTopY = 0.53;   // table top surface, 0.47 m above the floor
constexpr double kDeskPitch = 40.0;  // degrees down

void build_desk(Room& room) {
  room.plane({0, -1, 0}, {0, kDeskFloorY, 0});             // floor
  room.plane({0, 0, -1}, {0, 0, 2.6});                     // back wall
  room.box({0, kDeskTopY + 0.02, 1.0}, {0.5, 0.02, 0.3});  // table top
  const double leg_hh = (kDeskFloorY - kDeskTopY - 0.04) / 2;
  for (double x : {-0.45, 0.45})
    for (double z : {0.75, 1.25}) room.box({x, kDeskFloorY - leg_hh, z}, {0.025, leg_hh, 0.025});
  room.box({-0.2, kDeskTopY - 0.1, 1.0}, {0.1, 0.1, 0.08}, deg(20));    // box on the table
  room.cylinder({0.22, kDeskTopY - 0.06, 0.9}, {0, 1, 0}, 0.04, 0.06);  // mug
}

const std::vector<std::string>& scene_names() {
  static const std::vector<std::string> names = {"plane",  "tilted", "sphere", "box",
                                                 "stairs", "desk",   "moving"};
  return names;
}

}  // namespace

std::vector<std::string> Scene::names() { return scene_names(); }

Scene Scene::named(std::string_view name) {
  Scene s;
  if (name == "plane") {
    s.add_plane({0, 0, 1}, 0.8);
  } else if (name == "tilted") {
    const double a = deg(35);
    s.add_plane({std::sin(a), 0, std::cos(a)}, std::cos(a) * 1.0);
  } else if (name == "sphere") {
    s.add_sphere({0, 0, 0.7}, 0.15);
    s.add_plane({0, 0, 1}, 1.2);
  } else if (name == "box") {
    s.add_box({0, 0, 0.85}, {0.15, 0.15, 0.15});
    s.add_plane({0, 0, 1}, 1.1);
  } else if (name == "stairs") {
    Room room{s, pitch_down(deg(30))};
    constexpr double kFloorY = 1.3, kRise = 0.17, kTread = 0.28, kStart = 1.0;
    constexpr int kSteps = 4;
    room.plane({0, -1, 0}, {0, kFloorY, 0});
    const double back = kStart + kSteps * kTread;
    room.plane({0, 0, -1}, {0, 0, back});
    for (int k = 0; k < kSteps; ++k) {
      const double top = kFloorY - (k + 1) * kRise;
      const double front = kStart + k * kTread;
      room.box({0, (top + kFloorY) / 2, (front + back) / 2},
               {0.6, (kFloorY - top) / 2, (back - front) / 2});
    }
  } else if (name == "desk" || name == "moving") {
    Room room{s, pitch_down(deg(kDeskPitch))};
    build_desk(room);
    if (name == "moving") {
      const int ball = room.sphere({0, kDeskTopY - 0.06, 1.05}, 0.06);
      s.set_motion(ball, Motion{room.r * glm::dvec3(0.25, 0, 0), 4.0});
    }
  } else {
    std::string valid;
    for (const auto& n : scene_names()) valid += (valid.empty() ? "" : ", ") + n;
    throw std::invalid_argument("unknown synthetic scene '" + std::string(name) +
                                "'; valid scenes: " + valid);
  }
  return s;
}

// ---- Sensor model ------------------------------------------------------------------------------

SensorModel SensorModel::ideal() {
  SensorModel m;
  m.axial_noise = m.lateral_noise = m.quantise = m.shadow_holes = false;
  m.dropout_rate = 0.0;
  m.min_range_m = 0.0;
  m.max_range_m = 65.535;
  m.max_incidence_rad = kPi / 2;
  return m;
}

double axial_sigma_m(double z_m, double theta_rad) {
  double sigma = 0.0012 + 0.0019 * (z_m - 0.4) * (z_m - 0.4);
  if (theta_rad > deg(60)) {
    const double th = std::min(theta_rad, deg(89));  // the term diverges at grazing incidence
    const double g = kPi / 2 - th;
    sigma += 0.0001 * th * th / (std::sqrt(std::max(z_m, 1e-3)) * g * g);
  }
  return sigma;
}

double lateral_sigma_px(double theta_rad) {
  const double th = std::clamp(theta_rad, 0.0, deg(89));
  return 0.8 + 0.035 * th / (kPi / 2 - th);
}

namespace {

void check_render_inputs(const Intrinsics& intr, const SensorModel& sensor) {
  if (intr.width <= 0 || intr.height <= 0 || !(intr.fx > 0) || !(intr.fy > 0))
    throw std::invalid_argument("synth::render: intrinsics need width, height, fx, fy > 0");
  if (!(sensor.dropout_rate >= 0.0 && sensor.dropout_rate <= 1.0))
    throw std::invalid_argument("synth::render: SensorModel::dropout_rate must be in [0, 1]");
  if (!(sensor.min_range_m >= 0.0 && sensor.min_range_m < sensor.max_range_m))
    throw std::invalid_argument("synth::render: SensorModel needs 0 <= min_range_m < max_range_m");
}

using Geometry = Renderer::Geometry;

Geometry allocate_geometry(int w, int h) {
  return Geometry{cv::Mat1f(h, w, 0.0f), cv::Mat3f(h, w, cv::Vec3f(0, 0, 0)), cv::Mat1i(h, w, -1),
                  cv::Mat1f(h, w, 0.0f), cv::Mat1b(h, w, uchar{0})};
}

struct ColumnSpan {
  std::uint64_t bit;
  double u0, u1;
};

// Casts the rays of single pixels of one scene, one camera and its projector.
class PixelCaster {
 public:
  PixelCaster(const Scene& scene, const Intrinsics& intr, const glm::dvec3& t_cam_m,
              const SensorModel& sensor)
      : scene_(scene),
        intr_(intr),
        t_cam_(t_cam_m),
        sensor_(sensor),
        projector_(t_cam_m + glm::dvec3(sensor.baseline_m, 0, 0)),
        row_mask_(intr.height, ~std::uint64_t{0}),
        col_mask_(intr.width, ~std::uint64_t{0}),
        projector_rows_(intr.height),
        ray_x_(intr.width) {
    // Per-object screen rectangles from the camera (as row and column bit masks) and from the
    // projector, so each ray is tested only against the objects whose image covers it. The
    // projector only differs from the camera along x, so a surface point seen on camera row v
    // also lies on projector row v: each row keeps the objects whose projector rectangle spans it.
    for (const auto& b : scene.finite_bounds()) {
      if (b.id >= 64) continue;
      const std::uint64_t bit = std::uint64_t{1} << b.id;
      if (const auto rc = project_bound(b.corners, t_cam_, intr)) {
        for (int v = 0; v < intr.height; ++v)
          if (v < rc->v0 || v > rc->v1) row_mask_[v] &= ~bit;
        for (int u = 0; u < intr.width; ++u)
          if (u < rc->u0 || u > rc->u1) col_mask_[u] &= ~bit;
      }
      if (const auto rp = project_bound(b.corners, projector_, intr)) {
        projector_always_ &= ~bit;
        for (int v = std::max(0, static_cast<int>(std::ceil(rp->v0)));
             v < intr.height && v <= rp->v1; ++v)
          projector_rows_[v].push_back({bit, rp->u0, rp->u1});
      }
    }
    for (int u = 0; u < intr.width; ++u) ray_x_[u] = (u - intr.cx) / intr.fx;
  }

  // Fills pixel (u, v) of every map of `g` (which must be cleared there beforehand).
  void cast(int u, int v, Geometry& g) const {
    const double x = ray_x_[u], y = (v - intr_.cy) / intr_.fy;
    const glm::dvec3 dir = glm::dvec3(x, y, 1.0) * (1.0 / std::sqrt(x * x + y * y + 1.0));
    Hit hit;
    if (!scene_.cast_masked(t_cam_, dir, row_mask_[v] & col_mask_[u], hit)) return;
    glm::dvec3 n = hit.normal_camera;
    if (glm::dot(n, dir) > 0) n = -n;
    g.z_m(v, u) = static_cast<float>(hit.t_m * dir.z);
    g.normal(v, u) =
        cv::Vec3f(static_cast<float>(n.x), static_cast<float>(n.y), static_cast<float>(n.z));
    g.id(v, u) = hit.object_id;
    g.theta_rad(v, u) = static_cast<float>(theta_from_cos(-glm::dot(n, dir)));
    if (!sensor_.shadow_holes) return;
    const glm::dvec3 to = hit.p_camera - projector_;
    const double dist = glm::length(to);
    // Every object is convex or a plane, so it shadows itself exactly when it faces away from
    // the projector, and only the other objects need a shadow ray.
    if (glm::dot(n, to) >= 0) {
      g.shadowed(v, u) = 1;
      return;
    }
    std::uint64_t mask = projector_always_;
    if (to.z > 1e-9) {
      const double up = intr_.fx * to.x / to.z + intr_.cx;
      for (const ColumnSpan& span : projector_rows_[v])
        if (up >= span.u0 && up <= span.u1) mask |= span.bit;
    } else {
      mask = ~std::uint64_t{0};
    }
    if (scene_.blocked_masked(projector_, to * (1.0 / dist), dist * (1.0 - 1e-7), hit.object_id,
                              mask))
      g.shadowed(v, u) = 1;
  }

 private:
  const Scene& scene_;
  const Intrinsics& intr_;
  glm::dvec3 t_cam_;
  const SensorModel& sensor_;
  glm::dvec3 projector_;
  std::vector<std::uint64_t> row_mask_, col_mask_;
  std::vector<std::vector<ColumnSpan>> projector_rows_;
  std::uint64_t projector_always_ = ~std::uint64_t{0};
  std::vector<double> ray_x_;
};

// Sensor pass: each pixel draws its noise from a hash of (seed, frame, pixel).
cv::Mat1w apply_sensor(const Geometry& g, const SensorModel& sensor, std::uint64_t frame_index) {
  const int w = g.z_m.cols, h = g.z_m.rows;
  const auto& gauss = normal_table();
  const auto& raw_table = raw_depth_table();
  const std::uint64_t frame_key =
      splitmix64(splitmix64(sensor.seed) ^ (frame_index * 0xD1B54A32D192ED03ull));
  const double dropout_threshold = sensor.dropout_rate * 65536.0;
  cv::Mat1w depth_mm(h, w, kNoDepth);
  // Allocated whole, hence continuous: flat indexing keeps the per-pixel work small.
  const float* const z_true = g.z_m.ptr<float>();
  const int* const ids = g.id.ptr<int>();
  const float* const theta_map = g.theta_rad.ptr<float>();
  const uchar* const shadow_map = g.shadowed.ptr<uchar>();
  auto sensor_rows = [&](const cv::Range& rows) {
    for (int v = rows.start; v < rows.end; ++v) {
      std::uint16_t* dst = depth_mm[v];
      for (int u = 0; u < w; ++u) {
        const std::uint64_t r = splitmix64(frame_key + static_cast<std::uint64_t>(v) * w + u);
        const float g0 = gauss[r & 0xFFFF], g1 = gauss[(r >> 16) & 0xFFFF],
                    g2 = gauss[(r >> 32) & 0xFFFF];
        const double uniform = static_cast<double>(r >> 48) + 0.5;  // in (0, 65536)

        std::size_t src = static_cast<std::size_t>(v) * w + u;  // pixel the measurement samples
        double z = z_true[src];
        if (sensor.lateral_noise) {
          const double s = lateral_sigma_table(theta_map[src]);
          const double fu = std::clamp(u + s * g0, 0.0, w - 1.0);
          const double fv = std::clamp(v + s * g1, 0.0, h - 1.0);
          // fu, fv >= 0: truncation rounds
          src = static_cast<std::size_t>(static_cast<int>(fv + 0.5)) * w +
                static_cast<std::size_t>(static_cast<int>(fu + 0.5));
          z = z_true[src];
          if (w > 1 && h > 1) {
            const int u0 = std::min(static_cast<int>(fu), w - 2);
            const int v0 = std::min(static_cast<int>(fv), h - 2);
            const std::size_t i00 = static_cast<std::size_t>(v0) * w + u0, i10 = i00 + w;
            const int id = ids[i00];
            // Within one surface the jitter moves along it smoothly; across edges it picks a side.
            if (id >= 0 && ids[i00 + 1] == id && ids[i10] == id && ids[i10 + 1] == id) {
              const double a = fu - u0, b = fv - v0;
              z = (1 - b) * ((1 - a) * z_true[i00] + a * z_true[i00 + 1]) +
                  b * ((1 - a) * z_true[i10] + a * z_true[i10 + 1]);
            }
          }
        }
        if (!(z > 0.0)) continue;
        if (z < sensor.min_range_m || z > sensor.max_range_m) continue;
        if (shadow_map[src]) continue;
        const double theta = theta_map[src];
        if (theta > sensor.max_incidence_rad) continue;
        if (uniform < dropout_threshold) continue;
        if (sensor.axial_noise) z += axial_sigma_m(z, theta) * g2;
        if (sensor.quantise) {
          const double raw_f = depth_m_to_kinect_raw(z);
          if (!(raw_f >= 0.0)) continue;  // nearer than disparity 0
          const std::int64_t raw = static_cast<std::int64_t>(raw_f + 0.5);
          if (raw >= 1092) continue;  // beyond what 11 bits of disparity encode
          z = raw_table[raw];
        }
        const double mm = z * 1000.0 + 0.5;
        if (!(mm >= 1.0 && mm < 65536.0)) continue;
        dst[u] = static_cast<std::uint16_t>(mm);
      }
    }
  };
  cv::parallel_for_(cv::Range(0, h), sensor_rows);
  return depth_mm;
}

// Rows are independent (noise is hashed per pixel), so OpenCV's thread pool may split them; the
// result is identical for any thread count (cv::setNumThreads(1) runs serially).
void cast_all(const PixelCaster& caster, Geometry& g) {
  cv::parallel_for_(cv::Range(0, g.z_m.rows), [&](const cv::Range& rows) {
    for (int v = rows.start; v < rows.end; ++v)
      for (int u = 0; u < g.z_m.cols; ++u) caster.cast(u, v, g);
  });
}

}  // namespace

Rendered render(const Scene& scene, const Intrinsics& intr, const SensorModel& sensor,
                std::uint64_t frame_index) {
  return render_from(scene, intr, glm::dvec3(0.0), sensor, frame_index);
}

Rendered render_from(const Scene& scene, const Intrinsics& intr, const glm::dvec3& t_cam_m,
                     const SensorModel& sensor, std::uint64_t frame_index) {
  check_render_inputs(intr, sensor);
  Geometry g = allocate_geometry(intr.width, intr.height);
  cast_all(PixelCaster(scene, intr, t_cam_m, sensor), g);
  Rendered out;
  out.depth.depth_mm = apply_sensor(g, sensor, frame_index);
  out.depth.intrinsics = intr;
  out.true_depth_m = g.z_m;
  out.true_normals = g.normal;
  out.object_id = g.id;
  return out;
}

// ---- Incremental renderer ----------------------------------------------------------------------

Renderer::Renderer(const Intrinsics& intr, const SensorModel& sensor, const glm::dvec3& t_cam_m)
    : intr_(intr), sensor_(sensor), t_cam_m_(t_cam_m) {
  check_render_inputs(intr, sensor);
}

Rendered Renderer::render(const Scene& scene, std::uint64_t frame_index) {
  const int w = intr_.width, h = intr_.height;
  const PixelCaster caster(scene, intr_, t_cam_m_, sensor_);
  std::optional<std::vector<int>> moved;
  if (previous_) moved = scene.moved_since(*previous_);

  // Rectangles, from the camera and from the projector, of every moved object before and after.
  std::vector<PixelRect> camera_rects, projector_rects;
  bool full = !moved.has_value();
  if (!full) {
    const glm::dvec3 projector = t_cam_m_ + glm::dvec3(sensor_.baseline_m, 0, 0);
    for (const Scene* s : {static_cast<const Scene*>(&*previous_), &scene})
      for (const auto& b : s->finite_bounds()) {
        if (std::find(moved->begin(), moved->end(), b.id) == moved->end()) continue;
        const auto rc = project_bound(b.corners, t_cam_m_, intr_);
        const auto rp = project_bound(b.corners, projector, intr_);
        if (!rc || !rp) full = true;  // reaches behind a viewpoint: no bound, cast everything
        if (rc) camera_rects.push_back(*rc);
        if (rp) projector_rects.push_back(*rp);
      }
  }

  if (full) {
    geometry_ = allocate_geometry(w, h);
    cast_all(caster, geometry_);
    last_recast_ = static_cast<std::size_t>(w) * h;
  } else if (!moved->empty()) {
    // A pixel changes only if a moved object may cover it (camera rectangle) or may block the
    // projector ray to its surface point; that ray meets projector row v at column
    // u - fx * baseline / z, since the projector is offset along x only.
    std::vector<std::size_t> recast_per_row(h, 0);
    const double fx_b = intr_.fx * sensor_.baseline_m;
    cv::parallel_for_(cv::Range(0, h), [&](const cv::Range& rows) {
      for (int v = rows.start; v < rows.end; ++v) {
        for (int u = 0; u < w; ++u) {
          bool dirty = false;
          for (const PixelRect& r : camera_rects)
            dirty |= u >= r.u0 && u <= r.u1 && v >= r.v0 && v <= r.v1;
          if (!dirty && sensor_.shadow_holes && geometry_.id(v, u) >= 0) {
            const double up = u - fx_b / geometry_.z_m(v, u);
            for (const PixelRect& r : projector_rects)
              dirty |= up >= r.u0 && up <= r.u1 && v >= r.v0 && v <= r.v1;
          }
          if (!dirty) continue;
          geometry_.z_m(v, u) = 0.0f;
          geometry_.normal(v, u) = cv::Vec3f(0, 0, 0);
          geometry_.id(v, u) = -1;
          geometry_.theta_rad(v, u) = 0.0f;
          geometry_.shadowed(v, u) = 0;
          caster.cast(u, v, geometry_);
          ++recast_per_row[v];
        }
      }
    });
    last_recast_ = 0;
    for (std::size_t n : recast_per_row) last_recast_ += n;
  } else {
    last_recast_ = 0;
  }
  previous_ = scene;

  Rendered out;
  out.depth.depth_mm = apply_sensor(geometry_, sensor_, frame_index);
  out.depth.intrinsics = intr_;
  // Copies: the cache is updated in place on the next call.
  out.true_depth_m = geometry_.z_m.clone();
  out.true_normals = geometry_.normal.clone();
  out.object_id = geometry_.id.clone();
  return out;
}

}  // namespace telex::synth
