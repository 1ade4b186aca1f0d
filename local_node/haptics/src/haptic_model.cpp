// SPDX-License-Identifier: MIT
// God-point proxy, stick/slip friction and the safety stages (ramps, clamp, rate limit, observer).
#include "telex/haptics/haptic_model.h"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <optional>
#include <stdexcept>
#include <tuple>

namespace telex {

namespace {

bool finite3(const glm::dvec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

void require(bool ok, const char* field, const char* rule) {
  if (!ok) throw std::invalid_argument(std::string("HapticParams.") + field + " must be " + rule);
}

// Samples per pixel of projected motion when marching a segment: two keeps a one-pixel-wide
// object from slipping between samples. The cap bounds the worst case (a teleport across the
// whole image) to a few tens of microseconds.
constexpr double kSamplesPerPixel = 2.0;
constexpr int kMaxMarchSamples = 2048;
constexpr int kBisections = 12;

}  // namespace

std::string_view to_string(FingertipStatus s) {
  switch (s) {
    case FingertipStatus::Ok:
      return "ok";
    case FingertipStatus::NoSurface:
      return "no-surface";
    case FingertipStatus::StaleSurface:
      return "stale-surface";
    case FingertipStatus::TrackingLost:
      return "tracking-lost";
    case FingertipStatus::OutsideImage:
      return "outside-image";
    case FingertipStatus::Hole:
      return "hole";
    case FingertipStatus::BehindCamera:
      return "behind-camera";
  }
  return "unknown";
}

std::string_view to_string(TickStatus s) {
  switch (s) {
    case TickStatus::Ok:
      return "ok";
    case TickStatus::TimeWentBackwards:
      return "time-went-backwards";
    case TickStatus::LongGap:
      return "long-gap";
    case TickStatus::BadSpan:
      return "bad-span";
  }
  return "unknown";
}

void HapticParams::validate() const {
  auto pos = [](double v) { return std::isfinite(v) && v > 0.0; };
  auto nonneg = [](double v) { return std::isfinite(v) && v >= 0.0; };
  require(pos(stiffness_N_per_m), "stiffness_N_per_m", "finite and > 0");
  require(pos(proxy_epsilon_m) && proxy_epsilon_m < 0.01, "proxy_epsilon_m", "in (0, 0.01) m");
  require(nonneg(mu_static), "mu_static", "finite and >= 0");
  require(nonneg(mu_dynamic), "mu_dynamic", "finite and >= 0");
  require(nonneg(slip_hysteresis) && slip_hysteresis <= 1.0, "slip_hysteresis", "in [0, 1]");
  require(pos(max_force_N), "max_force_N", "finite and > 0");
  require(pos(max_force_step_N), "max_force_step_N", "finite and > 0");
  require(nonneg(startup_ramp_s), "startup_ramp_s", "finite and >= 0");
  require(nonneg(fade_out_s), "fade_out_s", "finite and >= 0");
  require(pos(stale_limit_s), "stale_limit_s", "finite and > 0");
  require(nonneg(crossfade_s), "crossfade_s", "finite and >= 0");
  require(pos(pushout_speed_m_per_s), "pushout_speed_m_per_s", "finite and > 0");
  require(nonneg(virtual_damping_Ns_per_m), "virtual_damping_Ns_per_m", "finite and >= 0");
  require(nonneg(max_observer_damping_Ns_per_m), "max_observer_damping_Ns_per_m",
          "finite and >= 0");
  require(pos(nominal_period_s), "nominal_period_s", "finite and > 0");
  require(pos(max_tick_s) && max_tick_s >= nominal_period_s, "max_tick_s",
          "finite and >= nominal_period_s");
  require(nonneg(steps.abs_m) && nonneg(steps.rel) && steps.at(1.0) > 0.0, "steps",
          "non-negative with a positive tolerance");
}

double HapticParams::passive_stiffness_limit(double device_damping_Ns_per_m) const {
  return 2.0 * (device_damping_Ns_per_m - std::abs(virtual_damping_Ns_per_m)) / nominal_period_s;
}

// The surface the proxy sees during one tick: the current snapshot, cross-faded from the previous
// one over crossfade_s so a new frame never makes the force jump.
struct HapticModel::View {
  const Surface* cur = nullptr;
  const Surface* prev = nullptr;  // null once the fade is complete
  double alpha = 1.0;             // weight of cur
  StepTolerance steps;

  // A surface's query in the model's frame: p into its camera, the answer back.
  static SurfaceQuery plane_of(const Surface& s, const glm::dvec3& p, LocalPlane& out,
                               const StepTolerance& steps) {
    const SurfaceQuery q = local_plane(s, glm::transpose(s.R_ModelCamera) * p, out, steps);
    out.q_camera = s.R_ModelCamera * out.q_camera;
    out.n_camera = s.R_ModelCamera * out.n_camera;
    return q;
  }

  SurfaceQuery plane(const glm::dvec3& p, LocalPlane& out) const {
    const SurfaceQuery qc = plane_of(*cur, p, out, steps);
    if (prev == nullptr) return qc;
    LocalPlane old;
    const SurfaceQuery qp = plane_of(*prev, p, old, steps);
    if (qp != SurfaceQuery::Ok) return qc;
    if (qc != SurfaceQuery::Ok) {
      out = old;
      return qp;
    }
    // Both points lie on the same camera ray (when both surfaces share a camera), so the blend
    // stays on it.
    out.q_camera = old.q_camera + alpha * (out.q_camera - old.q_camera);
    const glm::dvec3 n = old.n_camera + alpha * (out.n_camera - old.n_camera);
    const double len = glm::length(n);
    if (len > 1e-9) out.n_camera = n / len;
    return SurfaceQuery::Ok;
  }

  // How far p lies behind the surface along its camera's ray through p (p's depth minus the
  // surface's there, in the camera of each surface; blended), and the surface's depth there; or
  // nothing where there is no data.
  bool behind(const glm::dvec3& p, double& d, double& z) const {
    const auto c = behind_of(*cur, p);
    if (prev == nullptr) {
      if (!c) return false;
      d = c->first;
      z = c->second;
      return true;
    }
    // Each frame projects with its own intrinsics (the stream may change resolution) and its own
    // camera (the head may have turned).
    const auto o = behind_of(*prev, p);
    if (c && o) {
      d = o->first + alpha * (c->first - o->first);
      z = o->second + alpha * (c->second - o->second);
    } else if (c) {
      std::tie(d, z) = *c;
    } else if (o) {
      std::tie(d, z) = *o;
    } else {
      return false;
    }
    return true;
  }

  std::optional<std::pair<double, double>> behind_of(const Surface& s,
                                                     const glm::dvec3& p_model) const {
    const glm::dvec3 p = glm::transpose(s.R_ModelCamera) * p_model;
    if (!(p.z > 1e-6)) return std::nullopt;
    const Intrinsics& k = s.intrinsics;
    const auto z = depth_at(s, k.fx * p.x / p.z + k.cx, k.fy * p.y / p.z + k.cy, steps);
    if (!z) return std::nullopt;
    return std::pair{p.z - *z, *z};
  }

  bool inside(const glm::dvec3& p) const {
    double d, z;
    return behind(p, d, z) && d > 0.0;
  }

  enum class Hit { None, Front, Side };
  // Walks from a (outside) towards b and stops at the first entry into the surface. A Front hit
  // enters through the visible surface (`stop` is on it); a Side hit enters through a step edge,
  // which the depth map does not show, so `stop` is the last free point before the edge.
  Hit march(const glm::dvec3& a_model, const glm::dvec3& b_model, glm::dvec3& stop) const {
    const Intrinsics& k = cur->intrinsics;
    int samples = kMaxMarchSamples;
    // How many pixels the segment crosses in the current surface's camera.
    const glm::dvec3 a = glm::transpose(cur->R_ModelCamera) * a_model;
    const glm::dvec3 b = glm::transpose(cur->R_ModelCamera) * b_model;
    if (a.z > 1e-6 && b.z > 1e-6) {
      const double du = k.fx * (b.x / b.z - a.x / a.z);
      const double dv = k.fy * (b.y / b.z - a.y / a.z);
      const double px = std::max(std::abs(du), std::abs(dv));
      samples =
          static_cast<int>(std::min<double>(kMaxMarchSamples, std::ceil(px * kSamplesPerPixel)));
      samples = std::max(samples, 1);
    }
    glm::dvec3 prev_s = a_model;
    for (int i = 1; i <= samples; ++i) {
      const glm::dvec3 s = a_model + (b_model - a_model) * (static_cast<double>(i) / samples);
      if (!inside(s)) {
        prev_s = s;
        continue;
      }
      glm::dvec3 lo = prev_s, hi = s;
      for (int j = 0; j < kBisections; ++j) {
        const glm::dvec3 mid = 0.5 * (lo + hi);
        (inside(mid) ? hi : lo) = mid;
      }
      double d_hi = 0.0, z_hi = 0.0;
      behind(hi, d_hi, z_hi);
      if (d_hi > steps.at(z_hi)) {
        stop = lo;
        return Hit::Side;
      }
      stop = hi;
      return Hit::Front;
    }
    stop = b_model;
    return Hit::None;
  }
};

HapticModel::HapticModel(const HapticParams& params, int fingertips)
    : params_(params), fingertips_(fingertips) {
  params_.validate();
  if (fingertips < 1 || fingertips > kMaxFingertips)
    throw std::invalid_argument("HapticModel: fingertips must be in [1, " +
                                std::to_string(kMaxFingertips) + "], got " +
                                std::to_string(fingertips));
}

void HapticModel::reset() {
  fingers_ = {};
  current_.reset();
  previous_.reset();
  has_time_ = false;
}

void HapticModel::update_proxy(Finger& f, const View& view, const glm::dvec3& x, double dt_s) {
  const double eps = params_.proxy_epsilon_m;
  const bool was_contact = f.contact;
  f.side_contact = false;
  if (!f.has_proxy) {
    f.proxy = x;
    f.has_proxy = true;
    f.contact = false;
  }

  // A new or moving surface may have jumped past the proxy: push it out along the normal, at a
  // bounded speed so the force builds up instead of kicking.
  LocalPlane pl;
  if (view.plane(f.proxy, pl) == SurfaceQuery::Ok) {
    const double h = glm::dot(pl.n_camera, f.proxy - pl.q_camera);
    if (h < eps) {
      const double step = std::min(eps - h, params_.pushout_speed_m_per_s * dt_s);
      f.proxy += step * pl.n_camera;
      if (h + step < 0.0) {
        // Still beneath the surface: hold here and push on.
        f.normal = pl.n_camera;
        f.penetration_m = std::max(0.0, glm::dot(pl.n_camera, f.proxy - x) - eps);
        f.contact = f.penetration_m > 0.0;
        f.raw_force =
            f.contact ? params_.stiffness_N_per_m * f.penetration_m * pl.n_camera : glm::dvec3(0.0);
        return;
      }
    }
  }

  // At most two constraint passes: slide on the plane, then (after walking off an edge) move
  // freely towards the device.
  for (int pass = 0; pass < 2; ++pass) {
    const bool on_plane = view.plane(f.proxy, pl) == SurfaceQuery::Ok;
    const double h_p = on_plane ? glm::dot(pl.n_camera, f.proxy - pl.q_camera) : 1e9;
    const bool resting = on_plane && h_p <= eps + params_.steps.at(pl.q_camera.z) * 0.25;
    const double h_x = resting ? glm::dot(pl.n_camera, x - pl.q_camera) : 1e9;

    if (!resting || h_x >= eps) {
      // Free proxy (or device lifted off the plane): go straight for the device.
      glm::dvec3 stop;
      const View::Hit hit = view.march(f.proxy, x, stop);
      if (hit == View::Hit::None) {
        f.proxy = x;
        f.contact = false;
        f.slipping = false;
      } else if (hit == View::Hit::Side) {
        f.proxy = stop;
        f.contact = true;
        f.side_contact = true;
      } else {
        LocalPlane at;
        if (view.plane(stop, at) == SurfaceQuery::Ok) {
          f.proxy = stop + (eps - glm::dot(at.n_camera, stop - at.q_camera)) * at.n_camera;
        } else {
          f.proxy = stop;
        }
        f.contact = true;
        if (!was_contact) f.slipping = false;
      }
      break;
    }

    // Device beneath the plane the proxy rests on: the frictionless goal is its projection.
    const glm::dvec3& n = pl.n_camera;
    const double depth = -h_x;  // how far the device is under the surface
    const glm::dvec3 goal = x + (eps - h_x) * n;
    if (!was_contact) f.slipping = false;
    const double mu_s = params_.mu_static, mu_d = params_.mu_dynamic;
    const glm::dvec3 dp = f.proxy - x;
    const double along = glm::dot(dp, n);
    const double tangential = glm::length(dp - along * n);
    const double theta = std::atan2(tangential, std::max(along, 1e-12));
    if (mu_d > mu_s) {
      f.slipping = true;
    } else if (f.slipping) {
      f.slipping = !(theta < params_.slip_hysteresis * std::atan(mu_d));
    } else {
      f.slipping = theta > std::atan(mu_s);
    }
    const double radius = (f.slipping ? mu_d : mu_s) * depth;
    const glm::dvec3 to_proxy = f.proxy - goal;
    const double dist = glm::length(to_proxy);
    // Inside the friction circle the proxy sticks; outside it is dragged to the circle's rim.
    const glm::dvec3 target = dist > radius ? goal + to_proxy * (radius / dist) : f.proxy;

    glm::dvec3 stop;
    const View::Hit hit = view.march(f.proxy, target, stop);
    f.contact = true;
    if (hit == View::Hit::Side) {
      f.proxy = stop;
      f.side_contact = true;
      break;
    }
    f.proxy = stop;
    // Follow the surface under the proxy's new position (curvature, small steps).
    LocalPlane next;
    const bool has_next = view.plane(f.proxy, next) == SurfaceQuery::Ok;
    const double h_next = has_next ? glm::dot(next.n_camera, f.proxy - next.q_camera) : 1e9;
    if (has_next && std::abs(h_next - eps) <= params_.steps.at(next.q_camera.z)) {
      f.proxy += (eps - h_next) * next.n_camera;
      pl = next;
      break;
    }
    // Walked off an edge or onto a hole: the proxy is free now, go again for the device.
    f.contact = false;
  }

  if (!f.contact) {
    f.penetration_m = 0.0;
    f.raw_force = glm::dvec3(0.0);
    return;
  }
  if (f.side_contact) {
    const glm::dvec3 d = f.proxy - x;
    const double len = glm::length(d);
    f.penetration_m = len;
    if (len > 1e-12) f.normal = d / len;
    f.raw_force = params_.stiffness_N_per_m * d;
    return;
  }
  LocalPlane at;
  if (view.plane(f.proxy, at) != SurfaceQuery::Ok) at = pl;
  f.normal = at.n_camera;
  // Measured from the surface (proxy minus eps), so eps never biases the force.
  const glm::dvec3 d = f.proxy - eps * at.n_camera - x;
  f.penetration_m = std::max(0.0, glm::dot(d, at.n_camera));
  if (f.penetration_m <= 0.0) {
    f.raw_force = glm::dvec3(0.0);
    f.contact = false;
    return;
  }
  f.raw_force = params_.stiffness_N_per_m * d;
}

TickStatus HapticModel::tick(std::int64_t now_ns, const std::shared_ptr<const Surface>& newest,
                             std::span<const FingertipInput> in, std::span<FingertipForce> out) {
  if (in.size() != static_cast<std::size_t>(fingertips_) || out.size() != in.size()) {
    ++counters_.bad_spans;
    return TickStatus::BadSpan;
  }
  ++counters_.ticks;
  TickStatus status = TickStatus::Ok;
  double dt_s = params_.nominal_period_s;
  if (has_time_) {
    if (now_ns <= last_ns_) {
      ++counters_.time_backwards;
      status = TickStatus::TimeWentBackwards;
    } else {
      dt_s = static_cast<double>(now_ns - last_ns_) * 1e-9;
      if (dt_s > params_.max_tick_s) {
        ++counters_.long_gaps;
        status = TickStatus::LongGap;
        dt_s = params_.max_tick_s;
      }
    }
  }
  has_time_ = true;
  last_ns_ = now_ns;

  if (newest && newest.get() != current_.get()) {
    if (current_ && newest->frame_id <= current_->frame_id) {
      ++counters_.surfaces_out_of_order;
    } else {
      previous_ = std::move(current_);
      current_ = newest;
      fade_start_ns_ = now_ns;
      ++counters_.surfaces_accepted;
    }
  }
  View view;
  view.steps = params_.steps;
  view.cur = current_.get();
  if (current_ && previous_ && params_.crossfade_s > 0.0) {
    const double since_s = static_cast<double>(now_ns - fade_start_ns_) * 1e-9;
    view.alpha = std::clamp(since_s / params_.crossfade_s, 0.0, 1.0);
    if (view.alpha < 1.0) view.prev = previous_.get();
  }
  bool fresh = false;
  if (current_) {
    const double age_s = std::abs(static_cast<double>(now_ns - current_->capture_ns)) * 1e-9;
    fresh = age_s <= params_.stale_limit_s;
    if (!fresh) ++counters_.stale_ticks;
  }

  const double up_rate = params_.startup_ramp_s > 0.0 ? 1.0 / params_.startup_ramp_s : 1e12;
  const double down_rate = params_.fade_out_s > 0.0 ? 1.0 / params_.fade_out_s : 1e12;
  const double k_T = dt_s;

  for (int i = 0; i < fingertips_; ++i) {
    Finger& f = fingers_[i];
    const FingertipInput& fin = in[i];
    FingertipForce& fo = out[i];
    const bool finite = finite3(fin.p_CameraFingertip) && finite3(fin.axis_Camera);
    if (!finite) ++counters_.nonfinite_inputs;
    bool sample_fresh = true;
    if (fin.sample_ns != FingertipInput::kUnknownTime) {
      const double age_s =
          (static_cast<double>(now_ns) - static_cast<double>(fin.sample_ns)) * 1e-9;
      sample_fresh = std::abs(age_s) <= params_.stale_limit_s;
      if (!sample_fresh) ++counters_.stale_tracking;
    }
    const bool tracked =
        fin.tracked && finite && sample_fresh && std::abs(fin.p_CameraFingertip.x) < 1e3 &&
        std::abs(fin.p_CameraFingertip.y) < 1e3 && std::abs(fin.p_CameraFingertip.z) < 1e3;

    const double target = (tracked && fresh) ? 1.0 : 0.0;
    const double gain_before = f.gain;
    if (target > f.gain) {
      f.gain = std::min(target, f.gain + up_rate * dt_s);
    } else if (target < f.gain) {
      f.gain = std::max(target, f.gain - down_rate * dt_s);
    }

    glm::dvec3 velocity(0.0);
    bool has_velocity = false;
    if (!tracked) {
      // Hold the force last felt and let the gain fade it; start afresh once tracking returns
      // since the finger may be anywhere by then. Held is the output (the rate limiter may still
      // have been rising towards the contact force): holding that target instead would let the
      // force grow after tracking was lost.
      if (f.status != FingertipStatus::TrackingLost)
        f.raw_force = gain_before > 0.0 ? f.out_force / gain_before : glm::dvec3(0.0);
      f.status = FingertipStatus::TrackingLost;
      f.has_proxy = false;
      f.has_prev_p = false;
      f.contact = false;
    } else if (current_ == nullptr) {
      f.status = FingertipStatus::NoSurface;
      f.proxy = fin.p_CameraFingertip;
      f.has_proxy = false;
      f.contact = false;
      f.raw_force = glm::dvec3(0.0);
    } else {
      const glm::dvec3& x = fin.p_CameraFingertip;
      update_proxy(f, view, x, dt_s);
      if (!fresh) {
        f.status = FingertipStatus::StaleSurface;
      } else if (f.contact) {
        f.status = FingertipStatus::Ok;
      } else {
        LocalPlane probe;
        switch (view.plane(x, probe)) {
          case SurfaceQuery::Ok:
            f.status = FingertipStatus::Ok;
            break;
          case SurfaceQuery::BehindCamera:
            f.status = FingertipStatus::BehindCamera;
            break;
          case SurfaceQuery::OutsideImage:
            f.status = FingertipStatus::OutsideImage;
            break;
          case SurfaceQuery::Hole:
            f.status = FingertipStatus::Hole;
            break;
        }
      }
      if (f.has_prev_p) {
        velocity = (x - f.prev_p) / k_T;
        has_velocity = true;
      }
      // Energy the environment absorbed over the last interval: the force that was applied
      // times the displacement it acted over (Hannaford/Ryu observer, exact for a held force).
      if (f.has_prev_p) f.observer_energy_J -= glm::dot(f.out_force, x - f.prev_p);
      f.prev_p = x;
      f.has_prev_p = true;
    }

    glm::dvec3 force = f.raw_force;
    if (f.contact && has_velocity) {
      force -= params_.virtual_damping_Ns_per_m * velocity;
      if (params_.passivity_observer) {
        const double v2 = glm::dot(velocity, velocity);
        if (f.observer_energy_J < 0.0 && v2 > 1e-12) {
          const double alpha =
              std::min(-f.observer_energy_J / (k_T * v2), params_.max_observer_damping_Ns_per_m);
          force -= alpha * velocity;
          ++counters_.observer_active;
        }
      }
    }
    if (params_.passivity_observer && f.contact && has_velocity) {
      // Force bounding: damping alone cannot stop a wall far above the passive stiffness from
      // kicking (its force switches on and off a tick late), so the force along the motion is
      // also cut to what the contact has absorbed and not yet returned.
      const double speed = glm::length(velocity);
      if (speed > 1e-9) {
        const glm::dvec3 dir = velocity / speed;
        const double along = glm::dot(force, dir);
        const double allowed = std::max(f.observer_energy_J, 0.0) / (k_T * speed);
        if (along > allowed) {
          force -= (along - allowed) * dir;
          ++counters_.observer_active;
        }
      }
    }
    // Energy generated on the way out of a contact (the force switches off a tick late) is a
    // debt paid with damping at the next touch; credit is forgotten between touches so an old
    // dissipative contact cannot hide energy generated by the next one.
    if (!f.contact && f.observer_energy_J > 0.0) f.observer_energy_J = 0.0;

    const double mag = glm::length(force);
    if (mag > params_.max_force_N) {
      force *= params_.max_force_N / mag;
      ++counters_.clamped;
    }
    force *= f.gain;
    const glm::dvec3 change = force - f.out_force;
    const double change_mag = glm::length(change);
    if (change_mag > params_.max_force_step_N) {
      force = f.out_force + change * (params_.max_force_step_N / change_mag);
      ++counters_.rate_limited;
    }
    if (!finite3(force))
      force = glm::dvec3(0.0);  // cannot happen with finite inputs; belt and braces
    f.out_force = force;

    fo.force_N = force;
    const glm::dvec3 n = f.normal;
    const double fn = glm::dot(force, n);
    fo.normal_force_N = std::max(0.0, fn);
    fo.tangential_force_N = force - fn * n;
    glm::dvec3 axis = fin.axis_Camera - glm::dot(fin.axis_Camera, n) * n;
    const double axis_len = finite ? glm::length(axis) : 0.0;
    fo.shear_along_axis_N =
        axis_len > 1e-9 ? glm::dot(fo.tangential_force_N, axis / axis_len) : 0.0;
    fo.contact = f.contact;
    fo.slipping = f.contact && f.slipping;
    fo.penetration_m = f.contact ? f.penetration_m : 0.0;
    fo.proxy_camera = f.proxy;
    fo.normal_camera = n;
    fo.gain = f.gain;
    fo.status = f.status;
  }
  return status;
}

}  // namespace telex
