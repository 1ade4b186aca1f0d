// SPDX-License-Identifier: MIT
// The force path's steps: clock, crossfade weight, tracking, gain, the god-point proxy (push-out,
// free move, stick/slip friction, slide, spring), passivity, clamp, rate limit and outputs.
#include "telex/haptics/detail/force_steps.h"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>

namespace telex::detail {

namespace {

bool finite3(const glm::dvec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

}  // namespace

TimeStep time_step(bool has_time, std::int64_t last_ns, std::int64_t now_ns,
                   const HapticParams& params, HapticCounters& counters) {
  TimeStep t{params.nominal_period_s, TickStatus::Ok};
  if (!has_time) return t;
  if (now_ns <= last_ns) {
    ++counters.time_backwards;
    t.status = TickStatus::TimeWentBackwards;
    return t;
  }
  t.dt_s = static_cast<double>(now_ns - last_ns) * 1e-9;
  if (t.dt_s > params.max_tick_s) {
    ++counters.long_gaps;
    t.status = TickStatus::LongGap;
    t.dt_s = params.max_tick_s;
  }
  return t;
}

double crossfade_weight(double since_s, double crossfade_s) {
  return std::clamp(since_s / crossfade_s, 0.0, 1.0);
}

bool fingertip_tracked(const FingertipInput& in, std::int64_t now_ns, const HapticParams& params,
                       HapticCounters& counters, bool& finite) {
  finite = finite3(in.p_ModelFingertip) && finite3(in.axis_Model);
  if (!finite) ++counters.nonfinite_inputs;
  bool sample_fresh = true;
  if (in.sample_ns != FingertipInput::kUnknownTime) {
    const double age_s = (static_cast<double>(now_ns) - static_cast<double>(in.sample_ns)) * 1e-9;
    sample_fresh = std::abs(age_s) <= params.stale_limit_s;
    if (!sample_fresh) ++counters.stale_tracking;
  }
  const glm::dvec3& p = in.p_ModelFingertip;
  return in.tracked && finite && sample_fresh && std::abs(p.x) < 1e3 && std::abs(p.y) < 1e3 &&
         std::abs(p.z) < 1e3;
}

double ramp_gain(double gain, double target, const HapticParams& params, double dt_s) {
  const double up_rate = params.startup_ramp_s > 0.0 ? 1.0 / params.startup_ramp_s : 1e12;
  const double down_rate = params.fade_out_s > 0.0 ? 1.0 / params.fade_out_s : 1e12;
  if (target > gain) return std::min(target, gain + up_rate * dt_s);
  if (target < gain) return std::max(target, gain - down_rate * dt_s);
  return gain;
}

void update_proxy(FingerState& f, const SurfaceView& view, const glm::dvec3& x,
                  const HapticParams& params, double dt_s) {
  const double eps = params.proxy_epsilon_m;
  const bool was_contact = f.contact;
  f.side_contact = false;
  if (!f.has_proxy) {
    f.p_ModelProxy = x;
    f.has_proxy = true;
    f.contact = false;
  }
  ModelPlane pl;
  if (push_out(f, view, x, params, dt_s, pl)) return;

  // At most two constraint passes: slide on the plane, then (after walking off an edge) move
  // freely towards the device.
  for (int pass = 0; pass < 2; ++pass) {
    const bool on_plane = view.plane(f.p_ModelProxy, pl) == SurfaceQuery::Ok;
    const double h_p = on_plane ? glm::dot(pl.normal_Model, f.p_ModelProxy - pl.p_ModelQ) : 1e9;
    const bool resting = on_plane && h_p <= eps + params.steps.at(pl.p_ModelQ.z) * 0.25;
    const double h_x = resting ? glm::dot(pl.normal_Model, x - pl.p_ModelQ) : 1e9;
    if (!resting || h_x >= eps) {
      move_free(f, view, x, was_contact, eps);
      break;
    }
    if (slide(f, view, x, h_x, params, was_contact, pl)) break;
  }
  spring_force(f, view, x, params, pl);
}

bool push_out(FingerState& f, const SurfaceView& view, const glm::dvec3& x,
              const HapticParams& params, double dt_s, ModelPlane& pl) {
  const double eps = params.proxy_epsilon_m;
  if (view.plane(f.p_ModelProxy, pl) != SurfaceQuery::Ok) return false;
  const glm::dvec3& n = pl.normal_Model;
  const double h = glm::dot(n, f.p_ModelProxy - pl.p_ModelQ);
  if (!(h < eps)) return false;
  // At a bounded speed, so the force builds up instead of kicking.
  const double step = std::min(eps - h, params.pushout_speed_m_per_s * dt_s);
  f.p_ModelProxy += step * n;
  if (!(h + step < 0.0)) return false;
  // Still beneath the surface: hold here and push on.
  f.normal_Model = n;
  f.penetration_m = std::max(0.0, glm::dot(n, f.p_ModelProxy - x) - eps);
  f.contact = f.penetration_m > 0.0;
  f.raw_force_N = f.contact ? params.stiffness_N_per_m * f.penetration_m * n : glm::dvec3(0.0);
  return true;
}

void move_free(FingerState& f, const SurfaceView& view, const glm::dvec3& x, bool was_contact,
               double eps_m) {
  glm::dvec3 stop;
  const SurfaceView::Hit hit = view.march(f.p_ModelProxy, x, stop);
  if (hit == SurfaceView::Hit::None) {
    f.p_ModelProxy = x;
    f.contact = false;
    f.slipping = false;
    return;
  }
  f.contact = true;
  if (hit == SurfaceView::Hit::Side) {
    f.p_ModelProxy = stop;
    f.side_contact = true;
    return;
  }
  ModelPlane at;
  if (view.plane(stop, at) == SurfaceQuery::Ok) {
    f.p_ModelProxy =
        stop + (eps_m - glm::dot(at.normal_Model, stop - at.p_ModelQ)) * at.normal_Model;
  } else {
    f.p_ModelProxy = stop;
  }
  if (!was_contact) f.slipping = false;
}

bool slip_state(bool slipping, const glm::dvec3& dp, const glm::dvec3& n, double mu_static,
                double mu_dynamic, double slip_hysteresis) {
  const double along = glm::dot(dp, n);
  const double tangential = glm::length(dp - along * n);
  const double theta = std::atan2(tangential, std::max(along, 1e-12));
  if (mu_dynamic > mu_static) return true;
  if (slipping) return !(theta < slip_hysteresis * std::atan(mu_dynamic));
  return theta > std::atan(mu_static);
}

glm::dvec3 friction_target(const glm::dvec3& p_ModelProxy, const glm::dvec3& goal,
                           double radius_m) {
  const glm::dvec3 to_proxy = p_ModelProxy - goal;
  const double dist = glm::length(to_proxy);
  return dist > radius_m ? goal + to_proxy * (radius_m / dist) : p_ModelProxy;
}

bool slide(FingerState& f, const SurfaceView& view, const glm::dvec3& x, double h_x,
           const HapticParams& params, bool was_contact, ModelPlane& pl) {
  const double eps = params.proxy_epsilon_m;
  const double mu_s = params.mu_static, mu_d = params.mu_dynamic;
  // The frictionless goal is the device's projection onto the plane.
  const glm::dvec3 n = pl.normal_Model;
  const double depth = -h_x;  // how far the device is under the surface
  const glm::dvec3 goal = x + (eps - h_x) * n;
  if (!was_contact) f.slipping = false;
  f.slipping = slip_state(f.slipping, f.p_ModelProxy - x, n, mu_s, mu_d, params.slip_hysteresis);
  const double radius = (f.slipping ? mu_d : mu_s) * depth;
  const glm::dvec3 target = friction_target(f.p_ModelProxy, goal, radius);

  glm::dvec3 stop;
  const SurfaceView::Hit hit = view.march(f.p_ModelProxy, target, stop);
  f.contact = true;
  f.p_ModelProxy = stop;
  if (hit == SurfaceView::Hit::Side) {
    f.side_contact = true;
    return true;
  }
  // Follow the surface under the proxy's new position (curvature, small steps).
  ModelPlane next;
  const bool has_next = view.plane(f.p_ModelProxy, next) == SurfaceQuery::Ok;
  const double h_next =
      has_next ? glm::dot(next.normal_Model, f.p_ModelProxy - next.p_ModelQ) : 1e9;
  if (has_next && std::abs(h_next - eps) <= params.steps.at(next.p_ModelQ.z)) {
    f.p_ModelProxy += (eps - h_next) * next.normal_Model;
    pl = next;
    return true;
  }
  f.contact = false;
  return false;
}

void spring_force(FingerState& f, const SurfaceView& view, const glm::dvec3& x,
                  const HapticParams& params, const ModelPlane& pl) {
  if (!f.contact) {
    f.penetration_m = 0.0;
    f.raw_force_N = glm::dvec3(0.0);
    return;
  }
  if (f.side_contact) {
    const glm::dvec3 d = f.p_ModelProxy - x;
    const double len = glm::length(d);
    f.penetration_m = len;
    if (len > 1e-12) f.normal_Model = d / len;
    f.raw_force_N = params.stiffness_N_per_m * d;
    return;
  }
  ModelPlane at;
  if (view.plane(f.p_ModelProxy, at) != SurfaceQuery::Ok) at = pl;
  f.normal_Model = at.normal_Model;
  // Measured from the surface (proxy minus eps), so eps never biases the force.
  const glm::dvec3 d = f.p_ModelProxy - params.proxy_epsilon_m * at.normal_Model - x;
  f.penetration_m = std::max(0.0, glm::dot(d, at.normal_Model));
  if (f.penetration_m <= 0.0) {
    f.raw_force_N = glm::dvec3(0.0);
    f.contact = false;
    return;
  }
  f.raw_force_N = params.stiffness_N_per_m * d;
}

glm::dvec3 passivity(glm::dvec3 force_N, const glm::dvec3& velocity, double energy_J, double dt_s,
                     const HapticParams& params, HapticCounters& counters) {
  force_N -= params.virtual_damping_Ns_per_m * velocity;
  if (!params.passivity_observer) return force_N;
  const double v2 = glm::dot(velocity, velocity);
  if (energy_J < 0.0 && v2 > 1e-12) {
    const double alpha = std::min(-energy_J / (dt_s * v2), params.max_observer_damping_Ns_per_m);
    force_N -= alpha * velocity;
    ++counters.observer_active;
  }
  // Force bounding: damping alone cannot stop a wall far above the passive stiffness from
  // kicking (its force switches on and off a tick late), so the force along the motion is also
  // cut to what the contact has absorbed and not yet returned.
  const double speed = glm::length(velocity);
  if (speed > 1e-9) {
    const glm::dvec3 dir = velocity / speed;
    const double along = glm::dot(force_N, dir);
    const double allowed = std::max(energy_J, 0.0) / (dt_s * speed);
    if (along > allowed) {
      force_N -= (along - allowed) * dir;
      ++counters.observer_active;
    }
  }
  return force_N;
}

glm::dvec3 clamp_force(glm::dvec3 force_N, double max_N, HapticCounters& counters) {
  const double mag = glm::length(force_N);
  if (mag > max_N) {
    force_N *= max_N / mag;
    ++counters.clamped;
  }
  return force_N;
}

glm::dvec3 rate_limit(glm::dvec3 force_N, const glm::dvec3& last_N, double max_step_N,
                      HapticCounters& counters) {
  const glm::dvec3 change = force_N - last_N;
  const double change_mag = glm::length(change);
  if (change_mag > max_step_N) {
    force_N = last_N + change * (max_step_N / change_mag);
    ++counters.rate_limited;
  }
  return force_N;
}

void write_output(const glm::dvec3& force_N, const FingerState& f, const glm::dvec3& axis_Model,
                  bool finite, FingertipForce& out) {
  out.force_N = force_N;
  const glm::dvec3 n = f.normal_Model;
  const double fn = glm::dot(force_N, n);
  out.normal_force_N = std::max(0.0, fn);
  out.tangential_force_N = force_N - fn * n;
  const glm::dvec3 axis = axis_Model - glm::dot(axis_Model, n) * n;
  const double axis_len = finite ? glm::length(axis) : 0.0;
  out.shear_along_axis_N =
      axis_len > 1e-9 ? glm::dot(out.tangential_force_N, axis / axis_len) : 0.0;
  out.contact = f.contact;
  out.slipping = f.contact && f.slipping;
  out.penetration_m = f.contact ? f.penetration_m : 0.0;
  out.p_ModelProxy = f.p_ModelProxy;
  out.normal_Model = n;
  out.gain = f.gain;
  out.status = f.status;
}

}  // namespace telex::detail
