// SPDX-License-Identifier: MIT
// Stability and accuracy suite of the haptic model: stiff walls, extreme inputs, analytic surfaces.
#include "telex/common/haptic_stability.h"

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

namespace telex {

namespace {

constexpr std::int64_t kTickNs = 1'000'000;
constexpr std::int64_t kFrameNs = 33'333'333;  // 30 Hz depth stream
constexpr double kTickS = 1e-3;

std::string fmt_num(double v) {
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
                             f.proxy_camera.x,
                             f.proxy_camera.y,
                             f.proxy_camera.z,
                             f.normal_camera.x,
                             f.normal_camera.y,
                             f.normal_camera.z,
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

std::string base_criteria(const HapticParams& p) {
  return "no NaN/Inf; |F| <= " + fmt_num(p.max_force_N) +
         " N; |dF| <= " + fmt_num(p.max_force_step_N) + " N/tick";
}

std::shared_ptr<const Surface> snapshot(const cv::Mat1f& depth_m, const Intrinsics& k,
                                        std::int64_t capture_ns, std::uint64_t id) {
  return std::make_shared<const Surface>(make_surface(depth_m, k, capture_ns, id));
}

// The same pixels re-published as a new frame, as the 30 Hz stream does for a static scene.
std::shared_ptr<const Surface> restamp(const std::shared_ptr<const Surface>& s,
                                       std::int64_t capture_ns, std::uint64_t id) {
  auto out = std::make_shared<Surface>(*s);
  out->capture_ns = capture_ns;
  out->frame_id = id;
  return out;
}

// Depth of the plane n . X = d (n unit, facing the camera); 0 where the ray misses it.
cv::Mat1f plane_depth(const Intrinsics& k, const glm::dvec3& n, double d) {
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
cv::Mat1f sphere_depth(const Intrinsics& k, const glm::dvec3& c, double r, double wall_z) {
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

  void publish(const cv::Mat1f& depth, const Intrinsics& k) {
    surface = snapshot(depth, k, now_ns, ++frame_id);
  }
  FingertipForce step(const glm::dvec3& x, bool tracked = true, std::int64_t dt_ns = kTickNs) {
    now_ns += dt_ns;
    if (republish && surface && now_ns - surface->capture_ns >= kFrameNs)
      surface = restamp(surface, now_ns, ++frame_id);
    FingertipInput in;
    in.p_camera = x;
    in.tracked = tracked;
    FingertipForce out;
    model.tick(now_ns, surface, std::span(&in, 1), std::span(&out, 1));
    mon.add(out);
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

StabilityCaseResult make_result(std::string name, std::string group) {
  StabilityCaseResult r;
  r.name = std::move(name);
  r.group = std::move(group);
  return r;
}

double wall_potential(double pen, double k, double f_max) {
  if (pen <= 0.0) return 0.0;
  if (k * pen <= f_max) return 0.5 * k * pen * pen;
  return f_max * pen - f_max * f_max / (2.0 * k);
}

}  // namespace

StabilityCaseResult grounded_wall_case(double k, bool observer, const GroundedDevice& dev) {
  HapticParams p;
  p.stiffness_N_per_m = k;
  p.max_force_N = 12.0;       // a Force Dimension class device
  p.max_force_step_N = 12.0;  // rate limit off: look at the bare sampled wall
  p.startup_ramp_s = 0.0;
  p.mu_static = p.mu_dynamic = 0.0;
  p.passivity_observer = observer;
  const Intrinsics kin = kinect_v1_intrinsics(160, 120);
  const double wall_z = 0.5;
  Driver drv(p);
  drv.publish(cv::Mat1f(kin.height, kin.width, static_cast<float>(wall_z)), kin);

  const double m = dev.mass_kg, b = dev.damping_Ns_per_m, fh = dev.hand_force_N;
  const int sub = std::max(1, dev.substeps);
  const double h = kTickS / sub;
  double z = wall_z - 0.01, v = dev.approach_speed_m_per_s;
  const double u_min = -fh * fh / (2.0 * k);
  auto excess = [&](double zz, double vv) {
    const double pen = zz - wall_z;
    return 0.5 * m * vv * vv + wall_potential(pen, k, p.max_force_N) - fh * pen - u_min;
  };
  const double e0 = excess(z, v);
  double work_J = 0.0, late_max = 0.0;
  const int ticks = static_cast<int>(dev.duration_s / kTickS);
  for (int i = 0; i < ticks; ++i) {
    const FingertipForce f = drv.step({0.01, 0.01, z});
    const double fz = f.force_N.z;
    for (int s = 0; s < sub; ++s) {
      v += h / m * (fz + fh - b * v);
      const double dz = h * v;
      work_J += fz * dz;
      z += dz;
    }
    if (!std::isfinite(z) || std::abs(z) > 1e3) break;  // a blow-up would otherwise run away
    if (i >= ticks - 500) late_max = std::max(late_max, excess(z, v));
  }
  const double ratio = std::isfinite(late_max) ? late_max / e0 : 1e300;
  const double bound = p.passive_stiffness_limit(b);
  StabilityCaseResult r =
      make_result(std::string("grounded k=") + fmt_num(k) + (observer ? " +observer" : "") +
                      (sub > 1 ? " sub=" + std::to_string(sub) : ""),
                  "stiffness-grounded");
  drv.mon.fill(r);
  r.energy_in_J = work_J;
  r.metrics = {
      {"stiffness_N_per_m", k},
      {"passivity_bound_N_per_m", bound},
      {"energy_ratio_end", ratio},
      {"device_mass_kg", m},
      {"device_damping_Ns_per_m", b},
      {"observer_active_ticks", static_cast<double>(drv.model.counters().observer_active)}};
  const bool settled = ratio < 1.0;
  const bool must_settle = k <= bound || observer;
  r.pass = drv.mon.base_ok(p) && (!must_settle || settled);
  r.criteria = base_criteria(p) + (must_settle ? "; excess energy at end < start" : "");
  r.note = settled ? "no growth: excess energy at end / start = " + fmt_num(ratio)
                   : "energy grows (ratio " + fmt_num(ratio) + "), bounded by the " +
                         fmt_num(p.max_force_N) + " N clamp";
  return r;
}

double largest_settling_stiffness(const GroundedDevice& device) {
  double best = -1.0;
  for (int i = 0; i <= 56; ++i) {
    const double k = 100.0 * std::pow(2.0, i / 4.0);
    if (k > 1e6 * 1.0001) break;
    const StabilityCaseResult r = grounded_wall_case(k, false, device);
    if (r.metrics[2].second >= 1.0) break;
    best = k;
  }
  return best;
}

StabilityCaseResult cutaneous_case(double k) {
  HapticParams p;
  p.stiffness_N_per_m = k;
  const Intrinsics kin = kinect_v1_intrinsics(320, 240);
  // The synthetic "tilted" plane (35 degrees, 1 m) seen through the Kinect-like sensor model, a
  // new noisy frame every 1/30 s, so the clamp and rate limit face real depth chatter.
  const synth::Scene scene = synth::Scene::named("tilted");
  const double a = 35.0 * M_PI / 180.0;
  const glm::dvec3 n(-std::sin(a), 0.0, -std::cos(a));
  const double d = glm::dot(n, glm::dvec3(0, 0, 1.0));
  std::vector<cv::Mat1f> frames;
  for (int i = 0; i < 8; ++i)
    frames.push_back(
        depth_m_from_mm(synth::render(scene, kin, synth::SensorModel{}, i).depth.depth_mm));
  Driver drv(p);
  drv.republish = false;
  std::size_t next = 0;
  auto new_frame = [&] { drv.publish(frames[next++ % frames.size()], kin); };
  new_frame();
  const glm::dvec3 q0(0.02, 0.01, (d - n.x * 0.02) / n.z);  // on the plane
  const glm::dvec3 t = glm::normalize(glm::cross(n, glm::dvec3(0, 1, 0)));
  const glm::dvec3 out = q0 + 0.02 * n, deep = q0 - 0.01 * n;
  std::vector<std::pair<glm::dvec3, int>> path = {
      {out, 2100}, {deep, 500}, {deep + 0.05 * t, 1000}, {deep - 0.05 * t, 1000},
      {out, 300},  {out, 200}};
  glm::dvec3 x = out;
  double max_raw = 0.0;
  for (const auto& [target, ticks] : path) {
    const glm::dvec3 from = x;
    for (int i = 1; i <= ticks; ++i) {
      x = from + (target - from) * (static_cast<double>(i) / ticks);
      if (drv.now_ns - drv.surface->capture_ns >= kFrameNs) new_frame();
      const FingertipForce f = drv.step(x);
      if (f.contact) max_raw = std::max(max_raw, f.penetration_m * k);
    }
  }
  StabilityCaseResult r = make_result("cutaneous k=" + fmt_num(k), "stiffness-cutaneous");
  drv.mon.fill(r);
  r.metrics = {{"stiffness_N_per_m", k},
               {"max_unclamped_force_N", max_raw},
               {"clamped_ticks", static_cast<double>(drv.model.counters().clamped)},
               {"rate_limited_ticks", static_cast<double>(drv.model.counters().rate_limited)}};
  r.pass = drv.mon.base_ok(p) && drv.mon.max_force > 0.0;
  r.criteria = base_criteria(p) + "; contact felt";
  r.note = "press 1 cm, stroke 10 cm on the sensor-model tilted plane; unclamped peak " +
           fmt_num(max_raw) + " N";
  return r;
}

namespace {

// Common frame of an extreme case: default parameters, a scene, a scripted fingertip.
struct Extreme {
  HapticParams params;
  Driver drv;
  Extreme() : drv(params) {}
};

StabilityCaseResult finish(const char* name, const Driver& drv, bool extra_ok,
                           const std::string& extra_criteria, const std::string& note) {
  StabilityCaseResult r = make_result(name, "extreme");
  drv.mon.fill(r);
  r.pass = drv.mon.base_ok(drv.model.params()) && extra_ok;
  r.criteria = base_criteria(drv.model.params()) +
               (extra_criteria.empty() ? std::string() : "; " + extra_criteria);
  r.note = note;
  return r;
}

const Intrinsics kExtremeK = kinect_v1_intrinsics(320, 240);

glm::dvec3 on_ray(double u, double v, double z) { return back_project(kExtremeK, u, v, z); }

}  // namespace

std::vector<StabilityCaseResult> extreme_cases(std::uint64_t random_ticks, std::uint64_t seed) {
  std::vector<StabilityCaseResult> out;
  const Intrinsics& kin = kExtremeK;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();

  {  // All holes: nothing to touch anywhere.
    Driver drv{HapticParams{}};
    drv.publish(cv::Mat1f(kin.height, kin.width, 0.0f), kin);
    drv.warm_up(on_ray(160, 120, 0.5));
    bool any_contact = false;
    for (int i = 0; i < 2000; ++i)
      any_contact |= drv.step(on_ray(100 + i % 120, 120, 0.3 + 0.001 * i)).contact;
    out.push_back(finish("all-holes", drv, !any_contact && drv.mon.max_force == 0.0,
                         "never contact, zero force", "fingertip swept through 2 m of holes"));
  }
  {  // One valid pixel: a lone depth value with no neighbours for a normal.
    Driver drv{HapticParams{}};
    cv::Mat1f depth(kin.height, kin.width, 0.0f);
    depth(120, 160) = 0.8f;
    drv.publish(depth, kin);
    drv.warm_up(on_ray(160, 120, 0.7));
    drv.move(on_ray(160, 120, 0.7), on_ray(160, 120, 0.82), 500);
    drv.move(on_ray(160, 120, 0.82), on_ray(163, 121, 0.82), 500);
    out.push_back(finish("one-valid-pixel", drv, true, "",
                         "pressed 2 cm into the lone pixel and slid off it"));
  }
  {  // Depth 0 and the largest representable values (and NaN/Inf/negative in the raw map).
    Driver drv{HapticParams{}};
    cv::Mat1f depth(kin.height, kin.width, 65.535f);  // uint16 max in mm
    for (int v = 0; v < kin.height; ++v)
      for (int u = 0; u < kin.width; ++u) {
        const int c = (u + 3 * v) % 6;
        if (c == 0) depth(v, u) = 0.0f;
        if (c == 1) depth(v, u) = std::numeric_limits<float>::max();
        if (c == 2) depth(v, u) = std::numeric_limits<float>::quiet_NaN();
        if (c == 3) depth(v, u) = -std::numeric_limits<float>::infinity();
      }
    drv.publish(depth, kin);
    drv.warm_up(on_ray(160, 120, 1.0));
    drv.move(on_ray(160, 120, 1.0), on_ray(170, 125, 70.0), 1000);
    drv.move(on_ray(170, 125, 70.0), on_ray(150, 110, 0.5), 1000);
    out.push_back(finish("depth-0-and-max", drv, true, "",
                         "0, 65.535 m, FLT_MAX, NaN, -Inf pixels; pressed to 70 m and back"));
  }
  {  // 1 m step edge: stroke in contact from the near side over the edge and back.
    Driver drv{HapticParams{}};
    cv::Mat1f depth(kin.height, kin.width, 1.5f);
    depth(cv::Rect(0, 0, 160, kin.height)) = 0.5f;
    drv.publish(depth, kin);
    drv.warm_up(on_ray(100, 120, 0.45));
    drv.move(on_ray(100, 120, 0.45), on_ray(100, 120, 0.51), 300);
    drv.move(on_ray(100, 120, 0.51), on_ray(220, 120, 0.51), 500);  // off the edge
    drv.move(on_ray(220, 120, 0.51), on_ray(220, 120, 1.51), 500);  // down onto the far wall
    drv.move(on_ray(220, 120, 1.51), on_ray(100, 120, 1.51), 500);  // into the step's side
    const FingertipForce f = drv.step(on_ray(100, 120, 1.51));
    out.push_back(finish("step-edge-1m", drv, f.proxy_camera.z > 1.0,
                         "proxy stays on the far side of the step",
                         "over a 0.5 m / 1.5 m edge both ways while in contact"));
  }
  {  // 89-degree surface: a plane almost edge-on to the camera.
    Driver drv{HapticParams{}};
    const double a = 89.0 * M_PI / 180.0;
    const glm::dvec3 n(std::sin(a), 0.0, -std::cos(a));
    drv.publish(plane_depth(kin, n, glm::dot(n, glm::dvec3(0, 0, 1.0))), kin);
    drv.warm_up(on_ray(160, 120, 0.5));
    drv.move(on_ray(160, 120, 0.5), on_ray(160, 120, 1.2), 1000);
    drv.move(on_ray(160, 120, 1.2), on_ray(100, 150, 1.2), 1000);
    out.push_back(finish("surface-89deg", drv, true, "", "pressed through a plane at 89 degrees"));
  }
  {  // 1 m teleport in one tick, into the surface and back out.
    Driver drv{HapticParams{}};
    drv.publish(cv::Mat1f(kin.height, kin.width, 0.8f), kin);
    drv.warm_up(on_ray(160, 120, 0.7));
    drv.move(on_ray(160, 120, 0.7), on_ray(160, 120, 0.805), 100);
    FingertipForce f = drv.step(on_ray(160, 120, 1.805));
    bool proxy_outside = f.proxy_camera.z < 0.8;
    for (int i = 0; i < 200; ++i)
      proxy_outside &= drv.step(on_ray(200, 60, 1.805)).proxy_camera.z < 0.8;
    drv.step(on_ray(160, 120, 0.3));
    f = drv.step(on_ray(160, 120, 0.3));
    out.push_back(finish("teleport-1m", drv, proxy_outside && !f.contact,
                         "proxy never passes the surface; free after the jump back",
                         "1 m jump into the wall, slide, 1.5 m jump out"));
  }
  {  // NaN and Inf from the tracker mid-contact.
    HapticParams p;
    Driver drv(p);
    drv.publish(cv::Mat1f(kin.height, kin.width, 0.8f), kin);
    drv.warm_up(on_ray(160, 120, 0.7));
    drv.move(on_ray(160, 120, 0.7), on_ray(160, 120, 0.81), 200);
    FingertipForce f;
    int ticks_to_zero = -1;
    for (int i = 0; i < 400; ++i) {
      const double bad = i % 2 ? nan : inf;
      f = drv.step({bad, 0.0, bad});
      if (ticks_to_zero < 0 && glm::length(f.force_N) == 0.0) ticks_to_zero = i + 1;
    }
    const int limit = static_cast<int>(std::ceil(p.fade_out_s / kTickS)) + 1;
    out.push_back(finish(
        "tracker-nan-inf", drv,
        f.status == FingertipStatus::TrackingLost && ticks_to_zero > 0 && ticks_to_zero <= limit,
        "force reaches zero within fade_out_s",
        "zero after " + std::to_string(ticks_to_zero) + " ticks"));
  }
  {  // Fingertip outside the image.
    Driver drv{HapticParams{}};
    drv.publish(cv::Mat1f(kin.height, kin.width, 0.8f), kin);
    drv.warm_up(on_ray(160, 120, 0.7));
    // Leave the image in front of the wall, then go deeper than the wall outside the image.
    drv.move(on_ray(160, 120, 0.7), on_ray(-50, 120, 0.7), 200);
    bool any_contact = false;
    for (int i = 0; i < 1000; ++i)
      any_contact |= drv.step(on_ray(-50.0 - i, 120, 0.7 + 0.0002 * i)).contact;
    out.push_back(finish("outside-image", drv, !any_contact && drv.mon.max_force == 0.0,
                         "never contact, zero force",
                         "left the image in front of the wall, then went 20 cm deeper outside it"));
  }
  {  // Surfaces arriving out of order: older frames must be ignored.
    Driver drv{HapticParams{}};
    drv.republish = false;
    const cv::Mat1f near(kin.height, kin.width, 0.6f), far(kin.height, kin.width, 0.8f);
    drv.surface = snapshot(far, kin, 0, 100);
    drv.warm_up(on_ray(160, 120, 0.5));
    std::uint64_t id = 100;
    bool touched_old = false;
    for (int i = 0; i < 1000; ++i) {
      if (i % 33 == 0) {
        ++id;
        drv.surface = snapshot(far, kin, drv.now_ns, id);
      } else if (i % 33 == 10) {
        drv.surface = snapshot(near, kin, drv.now_ns, id - 50);  // a late, older frame
      }
      touched_old |= drv.step(on_ray(160, 120, 0.7)).contact;
    }
    const auto& c = drv.model.counters();
    out.push_back(finish("surfaces-out-of-order", drv, !touched_old && c.surfaces_out_of_order > 0,
                         "older frames ignored and counted",
                         std::to_string(c.surfaces_out_of_order) + " late frames ignored"));
  }
  {  // Stale surface: the stream stops; forces must ramp to zero.
    HapticParams p;
    Driver drv(p);
    drv.publish(cv::Mat1f(kin.height, kin.width, 0.8f), kin);
    drv.warm_up(on_ray(160, 120, 0.7));
    drv.move(on_ray(160, 120, 0.7), on_ray(160, 120, 0.81), 100);
    drv.republish = false;
    const std::int64_t stop_ns = drv.surface->capture_ns;
    FingertipForce f;
    std::int64_t zero_at = -1;
    for (int i = 0; i < 600; ++i) {
      f = drv.step(on_ray(160, 120, 0.81));
      if (zero_at < 0 && glm::length(f.force_N) == 0.0) zero_at = drv.now_ns;
    }
    const double t_zero = zero_at < 0 ? 1e9 : (zero_at - stop_ns) * 1e-9;
    out.push_back(finish("stale-surface", drv,
                         t_zero <= p.stale_limit_s + p.fade_out_s + 2 * kTickS &&
                             f.status == FingertipStatus::StaleSurface,
                         "zero force within stale_limit_s + fade_out_s of the last frame",
                         "zero " + fmt_num(t_zero) + " s after the last frame"));
  }
  {  // Timestamps going backwards mid-contact.
    Driver drv{HapticParams{}};
    drv.publish(cv::Mat1f(kin.height, kin.width, 0.8f), kin);
    drv.warm_up(on_ray(160, 120, 0.7));
    drv.move(on_ray(160, 120, 0.7), on_ray(160, 120, 0.81), 100);
    for (int i = 0; i < 200; ++i)
      drv.step(on_ray(160, 120, 0.81), true, i % 20 == 0 ? -500 * kTickNs : kTickNs);
    out.push_back(
        finish("time-backwards", drv, drv.model.counters().time_backwards == 10,
               "every backwards step counted",
               std::to_string(drv.model.counters().time_backwards) + " backwards steps of 0.5 s"));
  }
  {  // A 1 s gap between two ticks while in contact (the surface is re-sent during the gap).
    Driver drv{HapticParams{}};
    drv.publish(cv::Mat1f(kin.height, kin.width, 0.8f), kin);
    drv.warm_up(on_ray(160, 120, 0.7));
    drv.move(on_ray(160, 120, 0.7), on_ray(160, 120, 0.81), 100);
    drv.surface = restamp(drv.surface, drv.now_ns + 1'000'000'000, ++drv.frame_id);
    drv.step(on_ray(180, 120, 0.83), true, 1'000'000'000);
    for (int i = 0; i < 100; ++i) drv.step(on_ray(180, 120, 0.83));
    out.push_back(finish("gap-1s", drv, drv.model.counters().long_gaps == 1, "gap counted",
                         "1 s without ticks, fingertip moved 2 cm meanwhile"));
  }
  {  // Random fingertips and surfaces.
    HapticParams p;
    p.startup_ramp_s = 0.2;  // keep most of the run at full gain
    Driver drv(p);
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> uni(0.0, 1.0);
    std::normal_distribution<double> step(0.0, 0.002);
    std::vector<cv::Mat1f> scenes;
    scenes.emplace_back(kin.height, kin.width, 0.8f);
    {
      const double a = 60.0 * M_PI / 180.0;
      const glm::dvec3 n(std::sin(a), 0.0, -std::cos(a));
      scenes.push_back(plane_depth(kin, n, glm::dot(n, glm::dvec3(0, 0, 1.0))));
    }
    {
      cv::Mat1f s(kin.height, kin.width, 1.5f);
      s(cv::Rect(0, 0, 160, kin.height)) = 0.5f;
      scenes.push_back(s);
    }
    scenes.push_back(sphere_depth(kin, {0.0, 0.0, 0.7}, 0.15, 1.2));
    {
      cv::Mat1f s(kin.height, kin.width, 0.9f);
      cv::RNG r(3);
      cv::Mat1f holes(s.size());
      r.fill(holes, cv::RNG::UNIFORM, 0.0, 1.0);
      s.setTo(0.0f, holes < 0.3);
      scenes.push_back(s);
    }
    {
      cv::Mat1f s(kin.height, kin.width, 0.0f);
      s(120, 160) = 0.8f;
      scenes.push_back(s);
    }
    scenes.emplace_back(kin.height, kin.width, 0.0f);
    std::vector<std::shared_ptr<const Surface>> built;
    for (const auto& s : scenes) built.push_back(snapshot(s, kin, 0, 1));
    std::size_t scene = 0;
    drv.republish = false;
    drv.surface = restamp(built[0], 0, ++drv.frame_id);
    glm::dvec3 x(0.0, 0.0, 0.6);
    for (std::uint64_t i = 0; i < random_ticks; ++i) {
      const double r = uni(rng);
      std::int64_t dt = kTickNs;
      if (r < 0.001)
        dt = -static_cast<std::int64_t>(uni(rng) * 5e8);
      else if (r < 0.0015)
        dt = static_cast<std::int64_t>(uni(rng) * 1e9);
      if (uni(rng) < 0.002)
        scene = static_cast<std::size_t>(uni(rng) * built.size()) % built.size();
      if (drv.now_ns + dt - drv.surface->capture_ns >= kFrameNs || uni(rng) < 0.001) {
        // Mostly in order; now and then a late (older) frame id, or a frame that is already stale.
        const bool late = uni(rng) < 0.05;
        const std::int64_t cap = uni(rng) < 0.01 ? drv.now_ns - 400'000'000 : drv.now_ns + dt;
        drv.surface = restamp(built[scene], cap, late ? drv.frame_id - 3 : ++drv.frame_id);
      }
      const double t = uni(rng);
      if (t < 0.005) {
        x = {uni(rng) * 4 - 2, uni(rng) * 3 - 1.5, uni(rng) * 3.5 - 0.5};
      } else {
        x += glm::dvec3(step(rng), step(rng), step(rng));
        x.z = std::clamp(x.z, 0.2, 2.0);
        x.x = std::clamp(x.x, -0.6, 0.6);
        x.y = std::clamp(x.y, -0.45, 0.45);
      }
      glm::dvec3 fed = x;
      bool tracked = true;
      const double q = uni(rng);
      if (q < 0.0005)
        fed.x = nan;
      else if (q < 0.001)
        fed.z = -inf;
      else if (q < 0.0015)
        tracked = false;
      drv.step(fed, tracked, dt);
    }
    const auto& c = drv.model.counters();
    std::ostringstream note;
    note << random_ticks << " ticks over " << built.size() << " surfaces; " << c.time_backwards
         << " backwards, " << c.long_gaps << " gaps, " << c.surfaces_out_of_order
         << " late frames, " << c.nonfinite_inputs << " NaN/Inf inputs, " << c.clamped
         << " clamped";
    out.push_back(
        finish("random-combinations", drv, drv.mon.ticks == random_ticks, "", note.str()));
  }
  return out;
}

namespace {

struct AccuracyRun {
  double rms_error_N = 0.0;
  double peak_N = 0.0;
};

// Runs `path` (one point per tick) over `frames` (a new one every 1/30 s, cycling, as the
// stream would deliver them) and compares the force with the analytic one.
AccuracyRun accuracy_run(const std::vector<std::shared_ptr<const Surface>>& frames,
                         const HapticParams& p, const std::vector<glm::dvec3>& path,
                         const std::function<glm::dvec3(const glm::dvec3&)>& analytic,
                         Monitor& mon) {
  Driver drv(p);
  drv.republish = false;
  std::size_t next = 0;
  drv.surface = restamp(frames[next++ % frames.size()], 0, ++drv.frame_id);
  double sum2 = 0.0, peak = 0.0;
  for (const glm::dvec3& x : path) {
    if (drv.now_ns + kTickNs - drv.surface->capture_ns >= kFrameNs)
      drv.surface = restamp(frames[next++ % frames.size()], drv.now_ns + kTickNs, ++drv.frame_id);
    const FingertipForce f = drv.step(x);
    const glm::dvec3 ref = analytic(x);
    const glm::dvec3 e = f.force_N - ref;
    sum2 += glm::dot(e, e);
    peak = std::max(peak, glm::length(ref));
  }
  mon = drv.mon;
  return {std::sqrt(sum2 / static_cast<double>(path.size())), peak};
}

std::vector<glm::dvec3> polyline(const std::vector<std::pair<glm::dvec3, int>>& legs,
                                 const glm::dvec3& start) {
  std::vector<glm::dvec3> out;
  glm::dvec3 x = start;
  for (const auto& [to, ticks] : legs) {
    const glm::dvec3 from = x;
    for (int i = 1; i <= ticks; ++i) out.push_back(from + (to - from) * (double(i) / ticks));
    x = to;
  }
  return out;
}

// Noisy frames of the sensor model: enough distinct ones that the cycle does not matter.
constexpr int kNoisyFrames = 8;

}  // namespace

std::vector<StabilityCaseResult> accuracy_cases(bool with_sensor_noise) {
  std::vector<StabilityCaseResult> out;
  HapticParams p;
  p.stiffness_N_per_m = 400.0;
  p.mu_static = p.mu_dynamic = 0.0;  // the analytic reference is the frictionless contact force
  p.max_force_N = 1e3;
  p.max_force_step_N = 1e3;
  p.startup_ramp_s = 0.0;
  const Intrinsics kin = kinect_v1_intrinsics(640, 480);
  const double k = p.stiffness_N_per_m;

  // Surfaces of one scene: the exact ray-cast depth, the ideal sensor (exact, rounded to mm) and
  // the Kinect-like sensor model (noise, quantisation, shadows, dropouts), as the haptic loop
  // would receive them (normals from the depth itself).
  struct Variant {
    std::string name;
    std::vector<std::shared_ptr<const Surface>> frames;
    bool judged;  // noise-free: held to the 5 % criterion
  };
  auto variants = [&](const synth::Scene& scene) {
    std::vector<Variant> v;
    const synth::Rendered truth = synth::render(scene, kin, synth::SensorModel::ideal());
    v.push_back({"exact", {snapshot(truth.true_depth_m, kin, 0, 1)}, true});
    // Millimetre rounding alone is +-0.5 mm, 6 % RMS of a 5 mm penetration: reported, not judged.
    v.push_back({"ideal-mm", {snapshot(depth_m_from_mm(truth.depth.depth_mm), kin, 0, 1)}, false});
    if (with_sensor_noise) {
      Variant noisy{"sensor", {}, false};
      for (int i = 0; i < kNoisyFrames; ++i) {
        const synth::Rendered r = synth::render(scene, kin, synth::SensorModel{}, i);
        noisy.frames.push_back(snapshot(depth_m_from_mm(r.depth.depth_mm), kin, 0, 1));
      }
      v.push_back(std::move(noisy));
      // The same frames through the local daemon's surface stage with its default options
      // (hole-aware bilateral filter, box-averaged normals): the figure the operator feels.
      Variant filtered{"sensor-filtered", {}, false};
      for (int i = 0; i < kNoisyFrames; ++i) {
        const synth::Rendered r = synth::render(scene, kin, synth::SensorModel{}, i);
        cv::Mat1f depth_m = bilateral_filter_depth(r.depth.depth_mm);
        cv::Mat3f normals = compute_normals(depth_m, kin);
        filtered.frames.push_back(std::make_shared<const Surface>(
            make_surface(std::move(depth_m), kin, 0, 1, std::move(normals))));
      }
      v.push_back(std::move(filtered));
    }
    return v;
  };

  auto add = [&](const std::string& name, const Variant& var, const AccuracyRun& run,
                 const Monitor& mon, const std::string& what) {
    StabilityCaseResult r = make_result(name + " " + var.name, "accuracy");
    mon.fill(r);
    const double rel = run.peak_N > 0.0 ? run.rms_error_N / run.peak_N : 1.0;
    r.metrics = {{"rms_error_N", run.rms_error_N},
                 {"peak_force_N", run.peak_N},
                 {"rms_error_rel_peak", rel}};
    r.pass = mon.base_ok(p) && (!var.judged || rel <= 0.05);
    r.criteria =
        base_criteria(p) + (var.judged ? "; RMS force error <= 5 % of peak"
                                       : "; quantised/noisy: RMS error reported, not judged");
    r.note = what + ": RMS error " + fmt_num(rel * 100.0) + " % of peak";
    out.push_back(std::move(r));
  };

  {  // synth "tilted": plane at 1 m tilted 35 degrees about y (sin a x + cos a z = cos a).
    const double a = 35.0 * M_PI / 180.0;
    const glm::dvec3 n(-std::sin(a), 0.0, -std::cos(a));  // facing the camera
    const double d = glm::dot(n, glm::dvec3(0, 0, 1.0));
    auto analytic = [&](const glm::dvec3& x) {
      const double depth = d - glm::dot(n, x);  // > 0 beneath the surface
      return depth > 0.0 ? k * depth * n : glm::dvec3(0.0);
    };
    const glm::dvec3 q0(0.05, 0.03, (d - n.x * 0.05) / n.z);
    const glm::dvec3 t = glm::normalize(glm::cross(n, glm::dvec3(0, 1, 0)));
    const auto press = polyline({{q0 - 0.01 * n, 500}, {q0 + 0.01 * n, 500}}, q0 + 0.01 * n);
    const auto stroke =
        polyline({{q0 - 0.005 * n - 0.05 * t, 200}, {q0 - 0.005 * n + 0.05 * t, 1000}},
                 q0 + 0.01 * n - 0.05 * t);
    for (const Variant& var : variants(synth::Scene::named("tilted"))) {
      Monitor mon;
      add("plane-press", var, accuracy_run(var.frames, p, press, analytic, mon), mon,
          "35-degree plane, 1 cm press");
      add("plane-stroke", var, accuracy_run(var.frames, p, stroke, analytic, mon), mon,
          "35-degree plane, 10 cm stroke 5 mm deep");
    }
  }
  {  // synth "sphere": r 0.15 m at z 0.7 m in front of a wall at 1.2 m.
    const glm::dvec3 c(0.0, 0.0, 0.7);
    const double r = 0.15;
    auto analytic = [&](const glm::dvec3& x) {
      const glm::dvec3 dv = x - c;
      const double len = glm::length(dv);
      return len < r && len > 1e-9 ? k * (r - len) * (dv / len) : glm::dvec3(0.0);
    };
    const glm::dvec3 dir0 = glm::normalize(glm::dvec3(-0.3, -0.2, -1.0));
    const auto press = polyline({{c + (r - 0.01) * dir0, 500}, {c + (r + 0.01) * dir0, 500}},
                                c + (r + 0.01) * dir0);
    auto arc = [&](double deg) {
      const double th = deg * M_PI / 180.0;
      return glm::dvec3(std::sin(th), 0.0, -std::cos(th));
    };
    std::vector<glm::dvec3> stroke =
        polyline({{c + (r - 0.005) * arc(-40), 200}}, c + (r + 0.01) * arc(-40));
    for (int i = 1; i <= 1000; ++i)
      stroke.push_back(c + (r - 0.005) * arc(-40.0 + 80.0 * i / 1000));
    for (const Variant& var : variants(synth::Scene::named("sphere"))) {
      Monitor mon;
      add("sphere-press", var, accuracy_run(var.frames, p, press, analytic, mon), mon,
          "sphere, 1 cm press 20 degrees off axis");
      add("sphere-stroke", var, accuracy_run(var.frames, p, stroke, analytic, mon), mon,
          "sphere, 80-degree arc stroke 5 mm deep");
    }
  }
  return out;
}

std::vector<StabilityCaseResult> run_stability_suite(const StabilityOptions& options) {
  std::vector<StabilityCaseResult> all;
  for (double k : {100.0, 1e3, 1e4, 1e5, 1e6}) all.push_back(cutaneous_case(k));
  GroundedDevice dev;
  for (double k : {100.0, 400.0, 1e3, 1e4, 1e5, 1e6})
    all.push_back(grounded_wall_case(k, false, dev));
  for (double k : {1e3, 1e4, 1e5, 1e6}) all.push_back(grounded_wall_case(k, true, dev));
  // The same device integrated at 20 kHz behaves like the continuous one Colgate's bound is
  // about: above the bound it gains energy until the clamp holds it, unless the observer acts.
  GroundedDevice fine = dev;
  fine.substeps = 20;
  for (double k : {400.0, 1e4}) all.push_back(grounded_wall_case(k, false, fine));
  for (double k : {1e4, 1e6}) all.push_back(grounded_wall_case(k, true, fine));
  {
    StabilityCaseResult r = make_result("passivity-bound", "passivity");
    HapticParams p;
    const double bound = p.passive_stiffness_limit(dev.damping_Ns_per_m);
    const double k1 = largest_settling_stiffness(dev);
    const double k20 = largest_settling_stiffness(fine);
    r.metrics = {{"passivity_bound_N_per_m", bound},
                 {"largest_settling_k_1kHz_device_N_per_m", k1},
                 {"largest_settling_k_20kHz_device_N_per_m", k20}};
    r.pass = k1 >= bound && k20 >= bound;
    r.criteria = "every k up to 2b/T = " + fmt_num(bound) + " N/m settles (quarter-octave sweep)";
    r.note = "largest settling k: " + fmt_num(k1) + " N/m (device at 1 kHz), " + fmt_num(k20) +
             " N/m (device at 20 kHz, closer to continuous); bound 2b/T " + fmt_num(bound) + " N/m";
    all.push_back(std::move(r));
  }
  for (auto& r : extreme_cases(options.random_ticks, options.seed)) all.push_back(std::move(r));
  for (auto& r : accuracy_cases(true)) all.push_back(std::move(r));
  return all;
}

}  // namespace telex
