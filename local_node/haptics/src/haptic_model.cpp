// SPDX-License-Identifier: MIT
// The force model's tick: the steps of detail/force_steps.h in order, per fingertip; parameters.
#include "telex/haptics/haptic_model.h"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <stdexcept>

#include "telex/haptics/detail/force_steps.h"

namespace telex {

namespace {

bool finite3(const glm::dvec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

void require(bool ok, const char* field, const char* rule) {
  if (!ok) throw std::invalid_argument(std::string("HapticParams.") + field + " must be " + rule);
}

FingertipStatus status_of(SurfaceQuery q) {
  switch (q) {
    case SurfaceQuery::Ok:
      return FingertipStatus::Ok;
    case SurfaceQuery::BehindCamera:
      return FingertipStatus::BehindCamera;
    case SurfaceQuery::OutsideImage:
      return FingertipStatus::OutsideImage;
    case SurfaceQuery::Hole:
      return FingertipStatus::Hole;
  }
  return FingertipStatus::Hole;
}

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

void HapticModel::restart_output() {
  for (auto& f : fingers_) {
    f.out_force_N = glm::dvec3(0.0);
    f.gain = 0.0;
  }
}

void HapticModel::resume_output() {
  for (auto& f : fingers_) f.out_force_N = glm::dvec3(0.0);
}

void reexpress(const glm::dmat3& R_NewModel, std::span<FingertipForce> out) {
  for (auto& f : out) {
    f.force_N = R_NewModel * f.force_N;
    f.tangential_force_N = R_NewModel * f.tangential_force_N;
    f.p_ModelProxy = R_NewModel * f.p_ModelProxy;
    f.normal_Model = R_NewModel * f.normal_Model;
  }
}

void HapticModel::accept_surface(std::int64_t now_ns,
                                 const std::shared_ptr<const Surface>& newest) {
  if (!newest || newest.get() == current_.get()) return;
  if (current_ && newest->frame_id <= current_->frame_id) {
    ++counters_.surfaces_out_of_order;
    return;
  }
  previous_ = std::move(current_);
  current_ = newest;
  fade_start_ns_ = now_ns;
  ++counters_.surfaces_accepted;
}

TickStatus HapticModel::tick(std::int64_t now_ns, const std::shared_ptr<const Surface>& newest,
                             std::span<const FingertipInput> in, std::span<FingertipForce> out) {
  if (in.size() != static_cast<std::size_t>(fingertips_) || out.size() != in.size()) {
    ++counters_.bad_spans;
    return TickStatus::BadSpan;
  }
  ++counters_.ticks;
  const detail::TimeStep step = detail::time_step(has_time_, last_ns_, now_ns, params_, counters_);
  has_time_ = true;
  last_ns_ = now_ns;

  accept_surface(now_ns, newest);
  detail::SurfaceView view;
  view.steps = params_.steps;
  view.cur = current_.get();
  if (current_ && previous_ && params_.crossfade_s > 0.0) {
    const double since_s = static_cast<double>(now_ns - fade_start_ns_) * 1e-9;
    view.alpha = detail::crossfade_weight(since_s, params_.crossfade_s);
    if (view.alpha < 1.0) view.prev = previous_.get();
  }
  bool fresh = false;
  if (current_) {
    const double age_s = std::abs(static_cast<double>(now_ns - current_->capture_ns)) * 1e-9;
    fresh = age_s <= params_.stale_limit_s;
    if (!fresh) ++counters_.stale_ticks;
  }

  for (std::size_t i = 0; i < in.size(); ++i)
    finger_tick(fingers_[i], view, fresh, now_ns, step.dt_s, in[i], out[i]);
  return step.status;
}

void HapticModel::finger_tick(detail::FingerState& f, const detail::SurfaceView& view,
                              bool surface_fresh, std::int64_t now_ns, double dt_s,
                              const FingertipInput& fin, FingertipForce& fo) {
  bool finite = false;
  const bool tracked = detail::fingertip_tracked(fin, now_ns, params_, counters_, finite);
  const double gain_before = f.gain;
  f.gain = detail::ramp_gain(f.gain, (tracked && surface_fresh) ? 1.0 : 0.0, params_, dt_s);

  std::optional<glm::dvec3> velocity;
  if (!tracked) {
    // Hold the force last felt and let the gain fade it; start afresh once tracking returns
    // since the finger may be anywhere by then. Held is the output (the rate limiter may still
    // have been rising towards the contact force): holding that target instead would let the
    // force grow after tracking was lost.
    if (f.status != FingertipStatus::TrackingLost)
      f.raw_force_N = gain_before > 0.0 ? f.out_force_N / gain_before : glm::dvec3(0.0);
    f.status = FingertipStatus::TrackingLost;
    f.has_proxy = false;
    f.has_last_p = false;
    f.contact = false;
  } else if (view.cur == nullptr) {
    f.status = FingertipStatus::NoSurface;
    f.p_ModelProxy = fin.p_ModelFingertip;
    f.has_proxy = false;
    f.contact = false;
    f.raw_force_N = glm::dvec3(0.0);
  } else {
    velocity = contact(f, view, surface_fresh, fin.p_ModelFingertip, dt_s);
  }

  glm::dvec3 force = f.raw_force_N;
  if (f.contact && velocity)
    force = detail::passivity(force, *velocity, f.observer_energy_J, dt_s, params_, counters_);
  // Energy generated on the way out of a contact (the force switches off a tick late) is a
  // debt paid with damping at the next touch; credit is forgotten between touches so an old
  // dissipative contact cannot hide energy generated by the next one.
  if (!f.contact && f.observer_energy_J > 0.0) f.observer_energy_J = 0.0;
  force = detail::clamp_force(force, params_.max_force_N, counters_);
  force *= f.gain;
  force = detail::rate_limit(force, f.out_force_N, params_.max_force_step_N, counters_);
  if (!finite3(force)) force = glm::dvec3(0.0);  // cannot happen with finite inputs
  f.out_force_N = force;
  detail::write_output(force, f, fin.axis_Model, finite, fo);
}

std::optional<glm::dvec3> HapticModel::contact(detail::FingerState& f,
                                               const detail::SurfaceView& view, bool surface_fresh,
                                               const glm::dvec3& x, double dt_s) {
  detail::update_proxy(f, view, x, params_, dt_s);
  if (!surface_fresh) {
    f.status = FingertipStatus::StaleSurface;
  } else if (f.contact) {
    f.status = FingertipStatus::Ok;
  } else {
    detail::ModelPlane probe;
    f.status = status_of(view.plane(x, probe));
  }
  std::optional<glm::dvec3> velocity;
  if (f.has_last_p) {
    velocity = (x - f.p_ModelFingertipLast) / dt_s;
    // Energy the environment absorbed over the last interval: the force that was applied times
    // the displacement it acted over (Hannaford/Ryu observer, exact for a held force).
    f.observer_energy_J -= glm::dot(f.out_force_N, x - f.p_ModelFingertipLast);
  }
  f.p_ModelFingertipLast = x;
  f.has_last_p = true;
  return velocity;
}

}  // namespace telex
