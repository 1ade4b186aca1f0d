// SPDX-License-Identifier: MIT
// What the force model is given and gives (HapticParams, FingertipInput, FingertipForce, the
// counters) and one fingertip's state between ticks: shared by the model (haptic_model.h) and its
// steps (detail/force_steps.h).
#pragma once

#include <array>
#include <climits>
#include <cstdint>
#include <glm/mat3x3.hpp>
#include <glm/vec3.hpp>
#include <memory>
#include <optional>
#include <span>
#include <string>

#include "telex/haptics/haptic_surface.h"

namespace telex {

// Everything the model needs; units in the names. Defaults suit a cutaneous fingertip display
// driven at 1 kHz from a 30 Hz depth stream.
struct HapticParams {
  double stiffness_N_per_m = 400.0;  // Hooke's law along the normal
  // The proxy is kept this far on the free side so rounding never lets it slip under the
  // surface; the force is measured from the surface itself, so eps adds no bias.
  double proxy_epsilon_m = 1e-4;
  double mu_static = 0.5;
  double mu_dynamic = 0.3;
  // Slip -> stick when the device-proxy angle falls below this fraction of atan(mu_dynamic)
  // (CHAI3D's finger proxy uses 0.6): the gap between the two angles stops stick/slip chatter.
  double slip_hysteresis = 0.6;
  double max_force_N = 3.3;         // display limit: the output never exceeds it
  double max_force_step_N = 0.05;   // per tick; 50 N/s at 1 kHz
  double startup_ramp_s = 2.0;      // gain 0 -> 1 after start or recovery; 0 disables
  double fade_out_s = 0.1;          // gain 1 -> 0 when the surface or tracking is stale
  double stale_limit_s = 0.2;       // surface older than this (or tracking lost) fades out
  double crossfade_s = 1.0 / 30.0;  // a new surface is blended in over one frame
  double pushout_speed_m_per_s =
      0.5;  // a surface that jumped past the proxy pushes it out this fast
  double virtual_damping_Ns_per_m = 0.0;  // optional, applied in contact only
  bool passivity_observer = false;  // Hannaford/Ryu time-domain observer, for grounded devices
  double max_observer_damping_Ns_per_m = 20.0;
  double nominal_period_s = 1e-3;  // used when the clock goes backwards
  double max_tick_s = 0.01;        // longer gaps are counted and integrated as this
  StepTolerance steps{};

  // Throws std::invalid_argument naming the first bad field.
  void validate() const;
  // Colgate's passivity bound for this sample period: K_max = 2 (b - |B|) / T.
  double passive_stiffness_limit(double device_damping_Ns_per_m) const;
};

// One fingertip as the model is given it, in the Model frame.
struct FingertipInput {
  glm::dvec3 p_ModelFingertip{0.0};
  // Unit direction along the finger, for displays that render shear in one direction only.
  glm::dvec3 axis_Model{0.0, -1.0, 0.0};
  bool tracked = true;  // false when the tracker says it lost this fingertip
  // When the tracker sampled this position. A sample older than stale_limit_s is tracking loss
  // (a tracker that stopped reporting keeps repeating its last pose). kUnknownTime: not checked.
  std::int64_t sample_ns = kUnknownTime;
  static constexpr std::int64_t kUnknownTime = INT64_MIN;
};

enum class FingertipStatus : std::uint8_t {
  Ok,
  NoSurface,     // no snapshot received yet
  StaleSurface,  // the newest snapshot is older than stale_limit_s: fading out
  TrackingLost,  // tracker flag, NaN/Inf or stale sample: holding the last force and fading out
  OutsideImage,  // fingertip projects outside the depth image (not contact)
  Hole,          // no depth under the fingertip (not contact)
  BehindCamera,  // z <= 0: cannot project (not contact)
};
std::string_view to_string(FingertipStatus s);

// One fingertip's output; vectors in the Model frame (the frame of the inputs).
struct FingertipForce {
  glm::dvec3 force_N{0.0};             // on the finger, Model frame, after all safety stages
  double normal_force_N = 0.0;         // pressure along the contact normal (>= 0)
  glm::dvec3 tangential_force_N{0.0};  // shear (friction) in the contact plane, Model frame
  double shear_along_axis_N = 0.0;     // tangential force along the finger axis
  bool contact = false;
  bool slipping = false;
  double penetration_m = 0.0;
  glm::dvec3 p_ModelProxy{0.0};             // the god-point
  glm::dvec3 normal_Model{0.0, 0.0, -1.0};  // unit contact normal, towards the free side
  double gain = 0.0;                        // safety ramp applied, in [0, 1]
  FingertipStatus status = FingertipStatus::NoSurface;
};

enum class TickStatus : std::uint8_t {
  Ok,
  TimeWentBackwards,  // counted; integrated with nominal_period_s
  LongGap,            // counted; integrated with max_tick_s
  BadSpan,            // input/output spans do not match the fingertip count: nothing written
};
std::string_view to_string(TickStatus s);

struct HapticCounters {
  std::uint64_t ticks = 0;
  std::uint64_t time_backwards = 0;
  std::uint64_t long_gaps = 0;
  std::uint64_t bad_spans = 0;
  std::uint64_t surfaces_accepted = 0;
  std::uint64_t surfaces_out_of_order = 0;  // older or repeated frame ids: ignored
  std::uint64_t nonfinite_inputs = 0;       // NaN/Inf fingertip positions (tracking loss)
  std::uint64_t stale_ticks = 0;
  std::uint64_t stale_tracking = 0;  // fingertip samples older than stale_limit_s
  std::uint64_t clamped = 0;         // force limited to max_force_N
  std::uint64_t rate_limited = 0;    // force change limited to max_force_step_N
  std::uint64_t observer_active = 0;
};

namespace detail {
class SurfaceView;

// One fingertip's state between ticks, Model frame.
struct FingerState {
  bool has_proxy = false;
  glm::dvec3 p_ModelProxy{0.0};
  bool contact = false;
  bool slipping = false;
  bool side_contact = false;  // blocked by a step edge: force along proxy - device
  glm::dvec3 normal_Model{0.0, 0.0, -1.0};
  double penetration_m = 0.0;
  glm::dvec3 raw_force_N{0.0};  // before the safety stages, held through tracking loss
  glm::dvec3 out_force_N{0.0};  // last output, for the rate limit and the observer
  bool has_last_p = false;
  glm::dvec3 p_ModelFingertipLast{0.0};  // the device at the previous tracked tick
  double gain = 0.0;
  double observer_energy_J = 0.0;
  FingertipStatus status = FingertipStatus::NoSurface;
};
}  // namespace detail

}  // namespace telex
