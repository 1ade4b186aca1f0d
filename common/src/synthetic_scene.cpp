// SPDX-License-Identifier: MIT
// Synthetic scenes: the builders, animation, and the named scenes (plane, tilted, sphere, box,
// stairs, desk, moving).
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

void Scene::set_material(int object_id, Material material) {
  if (object_id < 0 || object_id >= next_id_)
    throw std::invalid_argument("set_material: no object " + std::to_string(object_id));
  if (materials_.size() <= static_cast<std::size_t>(object_id))
    materials_.resize(static_cast<std::size_t>(object_id) + 1, Material::Default);
  materials_[static_cast<std::size_t>(object_id)] = material;
}

Material Scene::material(int object_id) const {
  if (object_id < 0 || static_cast<std::size_t>(object_id) >= materials_.size())
    return Material::Default;
  return materials_[static_cast<std::size_t>(object_id)];
}

Scene Scene::seen_from(const glm::dmat3& R) const {
  Scene out = *this;
  out.R_CameraWorld_ = R * R_CameraWorld_;
  for (auto& p : out.planes_) p.n = R * p.n;
  for (auto& s : out.spheres_) {
    s.c0 = R * s.c0;
    s.c = R * s.c;
  }
  for (auto& b : out.boxes_) {
    b.c0 = R * b.c0;
    b.c = R * b.c;
    b.rot = R * b.rot;
  }
  for (auto& c : out.cylinders_) {
    c.c0 = R * c.c0;
    c.c = R * c.c;
    c.axis = R * c.axis;
  }
  for (auto& m : out.motions_) m.motion.amplitude_m = R * m.motion.amplitude_m;
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

// The furnished corner (Material): the camera 1.0 m above a plank floor, pitched 35 deg down at a
// wooden table whose book lies where the optical axis meets it (0.85 m ahead).
constexpr double kRoomPitch = 35.0;

void build_room(Room& room) {
  Scene& s = room.scene;
  s.set_texture_frame(room.r);
  s.set_material(room.plane({0, -1, 0}, {0, kDeskFloorY, 0}), Material::Floorboards);
  s.set_material(room.plane({0, 0, -1}, {0, 0, 2.2}), Material::Plaster);  // back wall
  s.set_material(room.plane({1, 0, 0}, {-1.1, 0, 0}), Material::Plaster);  // left wall
  s.set_material(room.box({0, kDeskTopY + 0.02, 0.8}, {0.55, 0.02, 0.35}), Material::Wood);
  const double leg_hh = (kDeskFloorY - kDeskTopY - 0.04) / 2;
  for (double x : {-0.5, 0.5})
    for (double z : {0.5, 1.1})
      s.set_material(room.box({x, kDeskFloorY - leg_hh, z}, {0.025, leg_hh, 0.025}),
                     Material::Wood);
  s.set_material(room.box({0.0, kDeskTopY - 0.02, 0.72}, {0.13, 0.02, 0.17}, deg(-4)),
                 Material::Book);
  s.set_material(room.box({-0.36, kDeskTopY - 0.09, 0.95}, {0.1, 0.09, 0.08}, deg(25)),
                 Material::Cardboard);
  s.set_material(room.cylinder({0.3, kDeskTopY - 0.05, 0.62}, {0, 1, 0}, 0.04, 0.05),
                 Material::Ceramic);
  s.set_material(room.sphere({0.33, kDeskTopY - 0.05, 0.95}, 0.05), Material::Metal);
}

const std::vector<std::string>& scene_names() {
  static const std::vector<std::string> names = {"plane",  "tilted", "sphere", "box",
                                                 "stairs", "desk",   "moving", "room"};
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
  } else if (name == "room") {
    Room room{s, pitch_down(deg(kRoomPitch))};
    build_room(room);
  } else {
    std::string valid;
    for (const auto& n : scene_names()) valid += (valid.empty() ? "" : ", ") + n;
    throw std::invalid_argument("unknown synthetic scene '" + std::string(name) +
                                "'; valid scenes: " + valid);
  }
  return s;
}

}  // namespace telex::synth
