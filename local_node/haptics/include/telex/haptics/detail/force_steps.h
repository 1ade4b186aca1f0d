// SPDX-License-Identifier: MIT
// Internal: the force path's steps (HapticModel::tick's numbered list), one function each, for
// haptic_model.cpp and its unit tests. Not an interface: nothing outside local_node/haptics and
// tests/haptics includes it. Everything here is in the Model frame (docs/NAMING.md).
#pragma once

#include <cstdint>
#include <glm/vec3.hpp>

#include "telex/haptics/haptic_surface.h"
#include "telex/haptics/haptic_types.h"

namespace telex::detail {

// A surface's local plane expressed in the Model frame: p_ModelQ on the surface (on the ray of
// the surface's camera through the queried point), normal_Model towards the free side.
struct ModelPlane {
  glm::dvec3 p_ModelQ{0.0};
  glm::dvec3 normal_Model{0.0, 0.0, -1.0};
};

// The surface the proxy sees during one tick: the current snapshot, cross-faded from the previous
// one over crossfade_s so a new frame never makes the force jump. Each snapshot is queried in its
// own camera (R_ModelCamera) and answers in the Model frame.
class SurfaceView {
 public:
  const Surface* cur = nullptr;
  const Surface* prev = nullptr;  // null once the fade is complete
  double alpha = 1.0;             // weight of cur
  StepTolerance steps;

  // One surface's plane under p_ModelQ; `out` is left as it was when the query fails.
  static SurfaceQuery plane_of(const Surface& s, const glm::dvec3& p_ModelQ, ModelPlane& out,
                               const StepTolerance& steps);
  // The blended plane under p_ModelQ (cur's alone where prev has none, and the reverse).
  SurfaceQuery plane(const glm::dvec3& p_ModelQ, ModelPlane& out) const;
  // How far p_ModelQ lies behind the surface along its camera's ray (its depth minus the
  // surface's there, in the camera of each surface; blended) as d, and the surface's depth there
  // as z; false where there is no data.
  bool behind(const glm::dvec3& p_ModelQ, double& d, double& z) const;
  bool inside(const glm::dvec3& p_ModelQ) const;

  enum class Hit { None, Front, Side };
  // Walks from a (outside) towards b and stops at the first entry into the surface. A Front hit
  // enters through the visible surface (`stop` is on it); a Side hit enters through a step edge,
  // which the depth map does not show, so `stop` is the last free point before the edge.
  Hit march(const glm::dvec3& p_ModelA, const glm::dvec3& p_ModelB, glm::dvec3& p_ModelStop) const;
};

// ---- tick's steps ----

// 1. Time step: the interval to integrate over and what was wrong with the clock (counted).
struct TimeStep {
  double dt_s = 0.0;
  TickStatus status = TickStatus::Ok;
};
TimeStep time_step(bool has_time, std::int64_t last_ns, std::int64_t now_ns,
                   const HapticParams& params, HapticCounters& counters);

// 3. Crossfade: the weight of the current surface, `since_s` after it arrived.
double crossfade_weight(double since_s, double crossfade_s);

// 4. Tracking: whether the fingertip counts as tracked; `finite` says whether its position and
// axis were finite (NaN/Inf and stale samples are counted).
bool fingertip_tracked(const FingertipInput& in, std::int64_t now_ns, const HapticParams& params,
                       HapticCounters& counters, bool& finite);

// 5. Gain: one tick's ramp of `gain` towards `target` (0 or 1): up over startup_ramp_s, down over
// fade_out_s (0: at once).
double ramp_gain(double gain, double target, const HapticParams& params, double dt_s);

// 6. Contact: the god-point proxy's step towards the device at x (p_ModelFingertip), then the
// spring force in f.raw_force_N. Its parts, in order:
void update_proxy(FingerState& f, const SurfaceView& view, const glm::dvec3& x,
                  const HapticParams& params, double dt_s);
// 6a. A surface that jumped past the proxy pushes it out along the normal at a bounded speed.
// True when the proxy is still beneath the surface: the force is set and the step is done.
bool push_out(FingerState& f, const SurfaceView& view, const glm::dvec3& x,
              const HapticParams& params, double dt_s, ModelPlane& pl);
// 6b. A free proxy (or a device lifted off the plane) goes straight for the device, stopping at
// the first entry into the surface.
void move_free(FingerState& f, const SurfaceView& view, const glm::dvec3& x, bool was_contact,
               double eps_m);
// 6c. Friction: stick/slip by the device-proxy angle (CHAI3D's finger proxy, with hysteresis).
// `dp` is proxy - device, `n` the unit normal.
bool slip_state(bool slipping, const glm::dvec3& dp, const glm::dvec3& n, double mu_static,
                double mu_dynamic, double slip_hysteresis);
// Inside the friction circle of `radius_m` about `goal` the proxy sticks; outside it is dragged to
// the circle's rim.
glm::dvec3 friction_target(const glm::dvec3& p_ModelProxy, const glm::dvec3& goal, double radius_m);
// 6d. Slide: the device is beneath the plane the proxy rests on; move by friction, then snap onto
// the surface there. True when the proxy ended on the surface (or at a step edge); false when it
// walked off an edge or onto a hole and is free again.
bool slide(FingerState& f, const SurfaceView& view, const glm::dvec3& x, double h_x,
           const HapticParams& params, bool was_contact, ModelPlane& pl);
// 6e. The spring force k (proxy - eps n - device), or k (proxy - device) at a step edge.
void spring_force(FingerState& f, const SurfaceView& view, const glm::dvec3& x,
                  const HapticParams& params, const ModelPlane& pl);

// 7. Damping and passivity, in contact with a velocity: virtual damping, then the observer's
// damping and force bound from the energy the contact absorbed (energy_J).
glm::dvec3 passivity(glm::dvec3 force_N, const glm::dvec3& velocity, double energy_J, double dt_s,
                     const HapticParams& params, HapticCounters& counters);

// 8. Clamp: the force's magnitude to max_N (counted).
glm::dvec3 clamp_force(glm::dvec3 force_N, double max_N, HapticCounters& counters);

// 9. Rate limit: at most max_step_N of change from the last output (counted).
glm::dvec3 rate_limit(glm::dvec3 force_N, const glm::dvec3& last_N, double max_step_N,
                      HapticCounters& counters);

// 10. Outputs: the force split along the normal, the shear along the finger's axis (projected on
// the contact plane; none when the axis was not finite), and the state.
void write_output(const glm::dvec3& force_N, const FingerState& f, const glm::dvec3& axis_Model,
                  bool finite, FingertipForce& out);

}  // namespace telex::detail
