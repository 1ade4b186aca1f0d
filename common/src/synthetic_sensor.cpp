// SPDX-License-Identifier: MIT
// The Kinect-v1-like sensor model applied to ray-cast geometry, whole-frame rendering and the
// incremental renderer.
#include <algorithm>
#include <array>
#include <cmath>
#include <glm/geometric.hpp>
#include <opencv2/core/utility.hpp>
#include <stdexcept>

#include "synthetic_internal.h"
#include "telex/common/opencv_workers.h"
#include "telex/common/synthetic.h"

namespace telex::synth {

using namespace detail;

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
  PixelCaster(const Scene& scene, const Intrinsics& intr, const glm::dvec3& p_CameraViewpoint,
              const SensorModel& sensor)
      : scene_(scene),
        intr_(intr),
        t_cam_(p_CameraViewpoint),
        sensor_(sensor),
        projector_(p_CameraViewpoint + glm::dvec3(sensor.baseline_m, 0, 0)),
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
    const glm::dvec3 to = hit.p_CameraHit - projector_;
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
  parallel_for(cv::Range(0, h), sensor_rows);
  return depth_mm;
}

// Rows are independent (noise is hashed per pixel), so OpenCV's thread pool may split them; the
// result is identical for any thread count (cv::setNumThreads(1) runs serially).
void cast_all(const PixelCaster& caster, Geometry& g) {
  parallel_for(cv::Range(0, g.z_m.rows), [&](const cv::Range& rows) {
    for (int v = rows.start; v < rows.end; ++v)
      for (int u = 0; u < g.z_m.cols; ++u) caster.cast(u, v, g);
  });
}

}  // namespace

Rendered render(const Scene& scene, const Intrinsics& intr, const SensorModel& sensor,
                std::uint64_t frame_index) {
  return render_from(scene, intr, glm::dvec3(0.0), sensor, frame_index);
}

Rendered render_from(const Scene& scene, const Intrinsics& intr,
                     const glm::dvec3& p_CameraViewpoint, const SensorModel& sensor,
                     std::uint64_t frame_index) {
  check_render_inputs(intr, sensor);
  Geometry g = allocate_geometry(intr.width, intr.height);
  cast_all(PixelCaster(scene, intr, p_CameraViewpoint, sensor), g);
  Rendered out;
  out.depth.depth_mm = apply_sensor(g, sensor, frame_index);
  out.depth.intrinsics = intr;
  out.true_depth_m = g.z_m;
  out.true_normals = g.normal;
  out.object_id = g.id;
  return out;
}

// ---- Incremental renderer ----------------------------------------------------------------------

Renderer::Renderer(const Intrinsics& intr, const SensorModel& sensor,
                   const glm::dvec3& p_CameraViewpoint)
    : intr_(intr), sensor_(sensor), p_CameraViewpoint_(p_CameraViewpoint) {
  check_render_inputs(intr, sensor);
}

Rendered Renderer::render(const Scene& scene, std::uint64_t frame_index) {
  const int w = intr_.width, h = intr_.height;
  const PixelCaster caster(scene, intr_, p_CameraViewpoint_, sensor_);
  std::optional<std::vector<int>> moved;
  if (previous_) moved = scene.moved_since(*previous_);

  // Rectangles, from the camera and from the projector, of every moved object before and after.
  std::vector<PixelRect> camera_rects, projector_rects;
  bool full = !moved.has_value();
  if (!full) {
    const glm::dvec3 projector = p_CameraViewpoint_ + glm::dvec3(sensor_.baseline_m, 0, 0);
    for (const Scene* s : {static_cast<const Scene*>(&*previous_), &scene})
      for (const auto& b : s->finite_bounds()) {
        if (std::find(moved->begin(), moved->end(), b.id) == moved->end()) continue;
        const auto rc = project_bound(b.corners, p_CameraViewpoint_, intr_);
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
    parallel_for(cv::Range(0, h), [&](const cv::Range& rows) {
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
