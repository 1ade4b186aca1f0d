// SPDX-License-Identifier: MIT
// Analytic ray casting of synthetic scenes and the Kinect-v1-like sensor model applied to it.
#include "telex/common/synthetic.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <glm/geometric.hpp>
#include <numbers>
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

// Pixel bounds of the image of a sphere (centre relative to the viewpoint) with one pixel of
// margin; nullopt when the sphere reaches the viewpoint's plane and must always be tested.
struct PixelRect {
  double u0, u1, v0, v1;
  bool contains(double u, double v) const { return u >= u0 && u <= u1 && v >= v0 && v <= v1; }
};
std::optional<PixelRect> project_bound(const glm::dvec3& c, double r, const Intrinsics& k) {
  const double z0 = c.z - r, z1 = c.z + r;
  if (z0 <= 1e-3) return std::nullopt;
  // x / z over the sphere's bounding box is extreme at its corners.
  const double xs[4] = {(c.x - r) / z0, (c.x - r) / z1, (c.x + r) / z0, (c.x + r) / z1};
  const double ys[4] = {(c.y - r) / z0, (c.y - r) / z1, (c.y + r) / z0, (c.y + r) / z1};
  const auto [x0, x1] = std::minmax_element(xs, xs + 4);
  const auto [y0, y1] = std::minmax_element(ys, ys + 4);
  return PixelRect{k.fx * *x0 + k.cx - 1, k.fx * *x1 + k.cx + 1, k.fy * *y0 + k.cy - 1,
                   k.fy * *y1 + k.cy + 1};
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

// ---- Ray casting -------------------------------------------------------------------------------

namespace {
bool in_mask(std::uint64_t mask, int id) { return id >= 64 || ((mask >> id) & 1u); }
}  // namespace

std::vector<Scene::Bound> Scene::finite_bounds() const {
  std::vector<Bound> out;
  for (const Sphere& s : spheres_) out.push_back({s.c, s.r, s.id});
  for (const Box& b : boxes_) out.push_back({b.c, b.bound_r, b.id});
  for (const Cylinder& c : cylinders_) out.push_back({c.c, c.bound_r, c.id});
  return out;
}

std::optional<Hit> Scene::raycast(const glm::dvec3& o, const glm::dvec3& d) const {
  return raycast_masked(o, d, ~std::uint64_t{0});
}

bool Scene::blocked(const glm::dvec3& o, const glm::dvec3& d, double max_t_m,
                    int skip_object) const {
  return blocked_masked(o, d, max_t_m, skip_object, ~std::uint64_t{0});
}

std::optional<Hit> Scene::raycast_masked(const glm::dvec3& o, const glm::dvec3& d,
                                         std::uint64_t mask) const {
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
  if (kind < 0) return std::nullopt;

  Hit hit{best, o + best * d, glm::dvec3(0.0), -1};
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
  return hit;
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

Rendered render(const Scene& scene, const Intrinsics& intr, const SensorModel& sensor,
                std::uint64_t frame_index) {
  return render_from(scene, intr, glm::dvec3(0.0), sensor, frame_index);
}

Rendered render_from(const Scene& scene, const Intrinsics& intr, const glm::dvec3& t_cam_m,
                     const SensorModel& sensor, std::uint64_t frame_index) {
  if (intr.width <= 0 || intr.height <= 0 || !(intr.fx > 0) || !(intr.fy > 0))
    throw std::invalid_argument("synth::render: intrinsics need width, height, fx, fy > 0");
  if (!(sensor.dropout_rate >= 0.0 && sensor.dropout_rate <= 1.0))
    throw std::invalid_argument("synth::render: SensorModel::dropout_rate must be in [0, 1]");
  if (!(sensor.min_range_m >= 0.0 && sensor.min_range_m < sensor.max_range_m))
    throw std::invalid_argument("synth::render: SensorModel needs 0 <= min_range_m < max_range_m");

  const int w = intr.width, h = intr.height;
  Rendered out;
  out.true_depth_m = cv::Mat1f(h, w, 0.0f);
  out.true_normals = cv::Mat3f(h, w, cv::Vec3f(0, 0, 0));
  out.object_id = cv::Mat1i(h, w, -1);
  cv::Mat1f incidence(h, w, 0.0f);     // angle between the camera ray and the surface normal (rad)
  cv::Mat1b shadowed(h, w, uchar{0});  // projector cannot reach the surface point

  const glm::dvec3 projector = t_cam_m + glm::dvec3(sensor.baseline_m, 0, 0);
  // Per-object screen rectangles from the camera (as row and column bit masks) and from the
  // projector, so each ray is tested only against the objects whose image covers it.
  const auto bounds = scene.finite_bounds();
  std::vector<std::uint64_t> row_mask(h, ~std::uint64_t{0}), col_mask(w, ~std::uint64_t{0});
  std::vector<std::pair<std::uint64_t, PixelRect>> projector_rects;
  std::uint64_t projector_always = ~std::uint64_t{0};
  for (const auto& b : bounds) {
    if (b.id >= 64) continue;
    const std::uint64_t bit = std::uint64_t{1} << b.id;
    if (const auto rc = project_bound(b.c - t_cam_m, b.r, intr)) {
      for (int v = 0; v < h; ++v)
        if (v < rc->v0 || v > rc->v1) row_mask[v] &= ~bit;
      for (int u = 0; u < w; ++u)
        if (u < rc->u0 || u > rc->u1) col_mask[u] &= ~bit;
    }
    if (const auto rp = project_bound(b.c - projector, b.r, intr)) {
      projector_always &= ~bit;
      projector_rects.emplace_back(bit, *rp);
    }
  }

  std::vector<double> ray_x(w);
  for (int u = 0; u < w; ++u) ray_x[u] = (u - intr.cx) / intr.fx;
  for (int v = 0; v < h; ++v) {
    float* zt = out.true_depth_m[v];
    cv::Vec3f* nt = out.true_normals[v];
    int* idt = out.object_id[v];
    float* ct = incidence[v];
    uchar* sh = shadowed[v];
    const double y = (v - intr.cy) / intr.fy;
    for (int u = 0; u < w; ++u) {
      const double x = ray_x[u];
      const glm::dvec3 dir = glm::dvec3(x, y, 1.0) * (1.0 / std::sqrt(x * x + y * y + 1.0));
      const auto hit = scene.raycast_masked(t_cam_m, dir, row_mask[v] & col_mask[u]);
      if (!hit) continue;
      glm::dvec3 n = hit->normal_camera;
      if (glm::dot(n, dir) > 0) n = -n;
      zt[u] = static_cast<float>(hit->t_m * dir.z);
      nt[u] = cv::Vec3f(static_cast<float>(n.x), static_cast<float>(n.y), static_cast<float>(n.z));
      idt[u] = hit->object_id;
      ct[u] = static_cast<float>(theta_from_cos(-glm::dot(n, dir)));
      if (sensor.shadow_holes) {
        const glm::dvec3 to = hit->p_camera - projector;
        const double dist = glm::length(to);
        // Every object is convex or a plane, so it shadows itself exactly when it faces away
        // from the projector, and only the other objects need a shadow ray.
        if (glm::dot(n, to) >= 0) {
          sh[u] = 1;
        } else {
          std::uint64_t mask = projector_always;
          if (to.z > 1e-9) {
            const double up = intr.fx * to.x / to.z + intr.cx, vp = intr.fy * to.y / to.z + intr.cy;
            for (const auto& [bit, rect] : projector_rects)
              if (rect.contains(up, vp)) mask |= bit;
          } else {
            mask = ~std::uint64_t{0};
          }
          if (scene.blocked_masked(projector, to * (1.0 / dist), dist * (1.0 - 1e-7),
                                   hit->object_id, mask))
            sh[u] = 1;
        }
      }
    }
  }

  // Sensor pass: each pixel draws its noise from a hash of (seed, frame, pixel).
  const auto& gauss = normal_table();
  const auto& raw_table = raw_depth_table();
  const std::uint64_t frame_key =
      splitmix64(splitmix64(sensor.seed) ^ (frame_index * 0xD1B54A32D192ED03ull));
  const double dropout_threshold = sensor.dropout_rate * 65536.0;
  out.depth.intrinsics = intr;
  out.depth.depth_mm = cv::Mat1w(h, w, kNoDepth);
  for (int v = 0; v < h; ++v) {
    std::uint16_t* dst = out.depth.depth_mm[v];
    for (int u = 0; u < w; ++u) {
      const std::uint64_t r = splitmix64(frame_key + static_cast<std::uint64_t>(v) * w + u);
      const float g0 = gauss[r & 0xFFFF], g1 = gauss[(r >> 16) & 0xFFFF],
                  g2 = gauss[(r >> 32) & 0xFFFF];
      const double uniform = static_cast<double>(r >> 48) + 0.5;  // in (0, 65536)

      int su = u, sv = v;  // pixel whose surface this measurement comes from
      double z = out.true_depth_m(v, u);
      if (sensor.lateral_noise) {
        const double s = lateral_sigma_table(incidence(v, u));
        const double fu = std::clamp(u + s * g0, 0.0, w - 1.0);
        const double fv = std::clamp(v + s * g1, 0.0, h - 1.0);
        su = static_cast<int>(fu + 0.5);  // fu, fv >= 0: truncation rounds
        sv = static_cast<int>(fv + 0.5);
        z = out.true_depth_m(sv, su);
        const int u0 = std::min(static_cast<int>(fu), w - 2 >= 0 ? w - 2 : 0);
        const int v0 = std::min(static_cast<int>(fv), h - 2 >= 0 ? h - 2 : 0);
        if (w > 1 && h > 1) {
          const int id = out.object_id(v0, u0);
          // Within one surface the jitter moves along it smoothly; across edges it picks a side.
          if (id >= 0 && out.object_id(v0, u0 + 1) == id && out.object_id(v0 + 1, u0) == id &&
              out.object_id(v0 + 1, u0 + 1) == id) {
            const double a = fu - u0, b = fv - v0;
            z = (1 - b) * ((1 - a) * out.true_depth_m(v0, u0) + a * out.true_depth_m(v0, u0 + 1)) +
                b * ((1 - a) * out.true_depth_m(v0 + 1, u0) + a * out.true_depth_m(v0 + 1, u0 + 1));
          }
        }
      }
      if (!(z > 0.0)) continue;
      if (z < sensor.min_range_m || z > sensor.max_range_m) continue;
      if (shadowed(sv, su)) continue;
      const double theta = incidence(sv, su);
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
  return out;
}

}  // namespace telex::synth
