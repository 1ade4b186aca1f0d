// SPDX-License-Identifier: MIT
// Stiff walls against the grounded device model, and the cutaneous display on a noisy plane.
#include "support.h"

namespace telex {

using namespace stability_detail;

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

}  // namespace telex
