// SPDX-License-Identifier: MIT
// Analytic synthetic scenes, a Kinect-v1-like structured-light sensor model, and ground truth.
#pragma once

#include <array>
#include <cstdint>
#include <glm/mat3x3.hpp>
#include <glm/vec3.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "telex/common/depth_image.h"

namespace telex::synth {

// A ray/surface intersection. `normal_camera` is the outward surface normal (unit).
struct Hit {
  double t_m;
  glm::dvec3 p_CameraHit;
  glm::dvec3 normal_camera;
  int object_id;
};

// Sinusoidal translation of one object: offset(t) = amplitude_m * sin(2 pi t / period_s).
// What an object is made of, for the eye video's shading (remote_node's synthetic view): depth
// and normals do not depend on it.
enum class Material : std::uint8_t {
  Default,      // a flat colour per object id
  Plaster,      // walls: off-white, mottled
  Floorboards,  // oak planks along the world's z, staggered joints
  Wood,         // table: grained
  Cardboard,    // a box with a tape stripe
  Ceramic,      // glazed, a blue band, glossy
  Metal,        // brushed, glossy
  Book,         // a red cloth cover, pale page edges
};

struct Motion {
  glm::dvec3 amplitude_m{0.0};
  double period_s = 1.0;
};

// An analytic scene in the camera frame (x right, y down, z forward, metres). Objects are
// infinite planes, spheres, oriented boxes and capped cylinders; every object gets an id (its
// index of insertion) that ray casts and renders report.
class Scene {
 public:
  // "plane" (wall facing the camera at 0.8 m), "tilted" (plane at 1.0 m tilted 35 deg about y),
  // "sphere" (r 0.15 m at z 0.7 m before a wall at 1.2 m), "box" (0.3 m cube face at 0.7 m before
  // a wall at 1.1 m: step edges), "stairs", "desk" (floor, table top, box, cylinder-like object),
  // "moving" (desk with a sphere moving sideways; the default of the remote daemon), "room" (a
  // furnished corner: plank floor, plaster walls, a wooden table with a book, a box, a mug and a
  // metal ball; the image centre falls on the book, where the demo presses and strokes).
  static Scene named(std::string_view name);  // throws std::invalid_argument naming the valid list
  static std::vector<std::string> names();

  // Builders. Planes are {p : dot(normal, p) = offset_m}; boxes have their half extents along the
  // columns of `rotation` (box frame -> camera frame); cylinders are capped, axis through `centre`.
  int add_plane(const glm::dvec3& normal, double offset_m);
  int add_sphere(const glm::dvec3& centre_m, double radius_m);
  int add_box(const glm::dvec3& centre_m, const glm::dvec3& half_extent_m,
              const glm::dmat3& rotation = glm::dmat3(1.0));
  int add_cylinder(const glm::dvec3& centre_m, const glm::dvec3& axis_unit, double radius_m,
                   double half_height_m);
  // Animates a sphere, box or cylinder (planes stay put). Throws std::invalid_argument on a bad id.
  void set_motion(int object_id, const Motion& motion);
  // Materials (Default until set; throws std::invalid_argument on a bad id) and the frame their
  // patterns are laid out in: R_CameraWorld, a level world (y down) for the room scenes.
  void set_material(int object_id, Material material);
  Material material(int object_id) const;
  void set_texture_frame(const glm::dmat3& R_CameraWorld) { R_CameraWorld_ = R_CameraWorld; }
  const glm::dmat3& texture_frame() const { return R_CameraWorld_; }

  Scene at_time(double t_s) const;  // animated objects move; static scenes unchanged
  // The scene seen from a camera turned about its centre: every object rotated by R_CameraScene
  // (p_camera = R_CameraScene p_scene). Take at_time first: motions are in the scene's frame.
  Scene seen_from(const glm::dmat3& R_CameraScene) const;
  bool animated() const;
  double time_s() const { return time_s_; }
  int object_count() const { return next_id_; }

  // Nearest hit with t > 0 along origin + t * dir_unit.
  std::optional<Hit> raycast(const glm::dvec3& origin, const glm::dvec3& dir_unit) const;
  // True when anything is hit with 1e-6 < t < max_t_m; `skip_object` (-1: none) is not tested.
  bool blocked(const glm::dvec3& origin, const glm::dvec3& dir_unit, double max_t_m,
               int skip_object = -1) const;

  // ---- lower level, for renderers ----
  // Corners of a box enclosing a finite object; renderers project them to skip objects per pixel.
  struct Bound {
    std::array<glm::dvec3, 8> corners;
    int id;
  };
  std::vector<Bound> finite_bounds() const;
  // As raycast/blocked, but finite objects with id < 64 are tested only when their bit in
  // `mask` is set (planes and ids >= 64 always are).
  bool cast_masked(const glm::dvec3& o, const glm::dvec3& d, std::uint64_t mask, Hit& hit) const;
  bool blocked_masked(const glm::dvec3& o, const glm::dvec3& d, double max_t_m, int skip_object,
                      std::uint64_t mask) const;
  // Ids of the objects whose geometry differs from `before` when both scenes hold the same
  // objects (e.g. two times of one animated scene); nullopt when they are different scenes.
  std::optional<std::vector<int>> moved_since(const Scene& before) const;

 private:
  struct Plane {
    glm::dvec3 n;
    double d;
    int id;
  };
  struct Sphere {
    glm::dvec3 c0, c;
    double r;
    int id;
  };
  struct Box {
    glm::dvec3 c0, c, h;
    glm::dmat3 rot;  // box frame -> camera frame
    double bound_r;
    int id;
  };
  struct Cylinder {
    glm::dvec3 c0, c, axis;
    double r, half_h, bound_r;
    int id;
  };
  struct Animated {
    int id;
    Motion motion;
  };

  void apply_time(double t_s);
  const Motion* motion_of(int id) const;

  std::vector<Plane> planes_;
  std::vector<Sphere> spheres_;
  std::vector<Box> boxes_;
  std::vector<Cylinder> cylinders_;
  std::vector<Animated> motions_;
  std::vector<Material> materials_;  // by id, Default beyond its end
  glm::dmat3 R_CameraWorld_{1.0};
  int next_id_ = 0;
  double time_s_ = 0.0;
};

struct SensorModel {          // Kinect-v1-like structured light
  bool axial_noise = true;    // Nguyen et al. 2012 sigma_z(z, theta)
  bool lateral_noise = true;  // Nguyen sigma_L(theta) in px: depth sampled at a jittered position
  bool quantise = true;       // disparity quantisation (step ~ 2.9e-3 z^2)
  bool shadow_holes =
      true;  // projector shadow at depth discontinuities (baseline_m to the projector)
  double dropout_rate = 0.003;  // random isolated holes
  double min_range_m = 0.4, max_range_m = 4.0;
  double baseline_m = 0.075;          // projector at +baseline_m along the camera's x axis
  double max_incidence_rad = 1.4835;  // 85 deg: grazing surfaces return no pattern (hole)
  std::uint64_t seed = 1;
  static SensorModel ideal();  // everything off: exact depth rounded to mm
};

struct Rendered {
  DepthImage depth;        // what the sensor reports, mm, 0 = hole
  cv::Mat1f true_depth_m;  // ground-truth z per pixel (0 where no surface)
  cv::Mat3f true_normals;  // ground-truth unit normals in the camera frame, facing the camera (0
                           // where none)
  cv::Mat1i object_id;     // id of the object seen at each pixel centre, -1 where none
};

// Ray-casts the scene at the pixel centres of `intr`; frame_index varies the noise seed
// deterministically. Throws std::invalid_argument on empty intrinsics or a bad sensor model.
Rendered render(const Scene& scene, const Intrinsics& intr, const SensorModel& sensor,
                std::uint64_t frame_index = 0);
// Ray-casts from a camera displaced by p_CameraViewpoint (camera-frame translation, e.g. a
// right-eye baseline); orientation unchanged. Depth, normals and ids are in the displaced camera's
// frame.
Rendered render_from(const Scene& scene, const Intrinsics& intr,
                     const glm::dvec3& p_CameraViewpoint, const SensorModel& sensor,
                     std::uint64_t frame_index = 0);

// Renders successive frames of one scene for one camera, like render_from, but re-casts only the
// pixels that the objects which moved since the previous frame can affect (their old and new
// screen rectangles, and the surface points whose projector ray passes their rectangles). A static
// scene costs only the sensor pass per frame; the output equals render_from's exactly.
class Renderer {
 public:
  // Throws std::invalid_argument on bad intrinsics or sensor model (as render does).
  Renderer(const Intrinsics& intr, const SensorModel& sensor,
           const glm::dvec3& p_CameraViewpoint = glm::dvec3(0.0));
  Rendered render(const Scene& scene, std::uint64_t frame_index);
  // Pixels ray-cast by the last render() (all of them on the first call or a new scene).
  std::size_t last_recast_pixels() const { return last_recast_; }

  struct Geometry {  // ground truth plus what the sensor pass needs, one entry per pixel
    cv::Mat1f z_m;
    cv::Mat3f normal;
    cv::Mat1i id;
    cv::Mat1f theta_rad;  // incidence angle between the camera ray and the normal
    cv::Mat1b shadowed;   // the projector cannot reach the surface point
  };

 private:
  Intrinsics intr_;
  SensorModel sensor_;
  glm::dvec3 p_CameraViewpoint_;
  std::optional<Scene> previous_;
  Geometry geometry_;
  std::size_t last_recast_ = 0;
};

// Nguyen, Izadi, Lovell 2012 axial noise sigma (m): 0.0012 + 0.0019 (z - 0.4)^2, plus
// 0.0001 theta^2 / (sqrt(z) (pi/2 - theta)^2) beyond 60 deg. theta is clamped below pi/2.
double axial_sigma_m(double z_m, double theta_rad);
// Nguyen lateral noise sigma in pixels: 0.8 + 0.035 theta / (pi/2 - theta).
double lateral_sigma_px(double theta_rad);

// Kinect raw 11-bit disparity <-> depth, NYU toolbox fit: z = 351.3 / (1092.5 - raw).
inline double kinect_raw_to_depth_m(double raw) { return 351.3 / (1092.5 - raw); }
inline double depth_m_to_kinect_raw(double z_m) { return 1092.5 - 351.3 / z_m; }

}  // namespace telex::synth
