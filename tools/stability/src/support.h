// SPDX-License-Identifier: MIT
// What the stability suite's cases share: the simulated device and fingertip driver, the monitor
// that checks every tick, and the analytic surfaces. Internal to tools/stability.
#pragma once

#include <algorithm>
#include <cmath>
#include <functional>
#include <glm/geometric.hpp>
#include <limits>
#include <memory>
#include <random>
#include <sstream>

#include "telex/common/bilateral.h"
#include "telex/common/normals.h"
#include "telex/common/synthetic.h"
#include "telex/stability/haptic_stability.h"

namespace telex::stability_detail {

constexpr std::int64_t kTickNs = 1'000'000;
constexpr std::int64_t kFrameNs = 33'333'333;  // 30 Hz depth stream
constexpr double kTickS = 1e-3;

inline std::string fmt_num(double v) {
  std::ostringstream os;
  os.precision(4);
  os << v;
  return os.str();
}

// Tracks the criteria every case shares, over every output field.
struct Monitor {
  double max_force = 0.0;
  double max_step = 0.0;
  std::uint64_t nonfinite = 0;
  std::uint64_t ticks = 0;
  glm::dvec3 prev{0.0};
  bool has_prev = false;

  void add(const FingertipForce& f) {
    ++ticks;
    const double fields[] = {f.force_N.x,
                             f.force_N.y,
                             f.force_N.z,
                             f.normal_force_N,
                             f.tangential_force_N.x,
                             f.tangential_force_N.y,
                             f.tangential_force_N.z,
                             f.shear_along_axis_N,
                             f.penetration_m,
                             f.p_ModelProxy.x,
                             f.p_ModelProxy.y,
                             f.p_ModelProxy.z,
                             f.normal_Model.x,
                             f.normal_Model.y,
                             f.normal_Model.z,
                             f.gain};
    bool finite = true;
    for (double v : fields)
      if (!std::isfinite(v)) {
        ++nonfinite;
        finite = false;
      }
    if (!finite) return;
    max_force = std::max(max_force, glm::length(f.force_N));
    if (has_prev) max_step = std::max(max_step, glm::length(f.force_N - prev));
    prev = f.force_N;
    has_prev = true;
  }

  bool base_ok(const HapticParams& p) const {
    return nonfinite == 0 && max_force <= p.max_force_N * (1.0 + 1e-12) &&
           max_step <= p.max_force_step_N * (1.0 + 1e-9);
  }

  void fill(StabilityCaseResult& r) const {
    r.max_force_N = max_force;
    r.max_force_step_N = max_step;
    r.nonfinite = nonfinite;
    r.ticks = ticks;
  }
};

inline std::string base_criteria(const HapticParams& p) {
  return "no NaN/Inf; |F| <= " + fmt_num(p.max_force_N) +
         " N; |dF| <= " + fmt_num(p.max_force_step_N) + " N/tick";
}

inline std::shared_ptr<const Surface> snapshot(const cv::Mat1f& depth_m, const Intrinsics& k,
                                               std::int64_t capture_ns, std::uint64_t id) {
  return std::make_shared<const Surface>(make_surface(depth_m, k, capture_ns, id));
}

// The same pixels re-published as a new frame, as the 30 Hz stream does for a static scene.
inline std::shared_ptr<const Surface> restamp(const std::shared_ptr<const Surface>& s,
                                              std::int64_t capture_ns, std::uint64_t id) {
  auto out = std::make_shared<Surface>(*s);
  out->capture_ns = capture_ns;
  out->frame_id = id;
  return out;
}

// Depth of the plane n . X = d (n unit, facing the camera); 0 where the ray misses it.
inline cv::Mat1f plane_depth(const Intrinsics& k, const glm::dvec3& n, double d) {
  cv::Mat1f m(k.height, k.width, 0.0f);
  for (int v = 0; v < k.height; ++v)
    for (int u = 0; u < k.width; ++u) {
      const glm::dvec3 ray((u - k.cx) / k.fx, (v - k.cy) / k.fy, 1.0);
      const double nr = glm::dot(n, ray);
      if (nr < -1e-12) {
        const double z = d / nr;
        if (z > 0.0) m(v, u) = static_cast<float>(z);
      }
    }
  return m;
}

// Sphere in front of a fronto-parallel wall, ray-cast at the pixel centres.
inline cv::Mat1f sphere_depth(const Intrinsics& k, const glm::dvec3& c, double r, double wall_z) {
  cv::Mat1f m(k.height, k.width, static_cast<float>(wall_z));
  for (int v = 0; v < k.height; ++v)
    for (int u = 0; u < k.width; ++u) {
      const glm::dvec3 ray((u - k.cx) / k.fx, (v - k.cy) / k.fy, 1.0);
      const glm::dvec3 dir = glm::normalize(ray);
      const double b = glm::dot(dir, c);
      const double disc = b * b - (glm::dot(c, c) - r * r);
      if (disc < 0.0) continue;
      const double t = b - std::sqrt(disc);
      if (t > 0.0) m(v, u) = static_cast<float>(t * dir.z);
    }
  return m;
}

// Drives one fingertip through a model, re-publishing the surface at 30 Hz.
struct Driver {
  explicit Driver(const HapticParams& p) : model(p, 1) {}
  HapticModel model;
  std::shared_ptr<const Surface> surface;
  std::int64_t now_ns = 0;
  std::uint64_t frame_id = 1;
  bool republish = true;
  Monitor mon;
  bool record = false;  // keep every tick in `trace`
  std::vector<StabilityTick> trace;

  void publish(const cv::Mat1f& depth, const Intrinsics& k) {
    surface = snapshot(depth, k, now_ns, ++frame_id);
  }
  FingertipForce step(const glm::dvec3& x, bool tracked = true, std::int64_t dt_ns = kTickNs) {
    now_ns += dt_ns;
    if (republish && surface && now_ns - surface->capture_ns >= kFrameNs)
      surface = restamp(surface, now_ns, ++frame_id);
    FingertipInput in;
    in.p_ModelFingertip = x;
    in.tracked = tracked;
    FingertipForce out;
    model.tick(now_ns, surface, std::span(&in, 1), std::span(&out, 1));
    mon.add(out);
    if (record) trace.push_back({now_ns, dt_ns, x, tracked, out});
    return out;
  }
  // Lets the start-up ramp finish with the fingertip in free space.
  void warm_up(const glm::dvec3& free_point) {
    const int n = static_cast<int>(std::ceil(model.params().startup_ramp_s / kTickS)) + 5;
    for (int i = 0; i < n; ++i) step(free_point);
  }
  // Straight line over `ticks` ticks.
  FingertipForce move(const glm::dvec3& a, const glm::dvec3& b, int ticks) {
    FingertipForce out;
    for (int i = 1; i <= ticks; ++i) out = step(a + (b - a) * (static_cast<double>(i) / ticks));
    return out;
  }
};

inline StabilityCaseResult make_result(std::string name, std::string group) {
  StabilityCaseResult r;
  r.name = std::move(name);
  r.group = std::move(group);
  return r;
}

inline double wall_potential(double pen, double k, double f_max) {
  if (pen <= 0.0) return 0.0;
  if (k * pen <= f_max) return 0.5 * k * pen * pen;
  return f_max * pen - f_max * f_max / (2.0 * k);
}

}  // namespace telex::stability_detail
