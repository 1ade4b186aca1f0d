// SPDX-License-Identifier: MIT
// Fingertip force model: god-point proxies on a depth surface, friction, and the 1 kHz safety
// layer. It works in the Model frame (docs/NAMING.md): the head base's during head teleoperation,
// the camera's otherwise; each surface says where its camera is in it (Surface::R_ModelCamera).
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
#include "telex/haptics/haptic_types.h"

namespace telex {

// Outputs as a model working in another frame would give them: every vector turned by R_NewModel
// (the Model frame's orientation in the new one). The station's logs, recording and views hold
// each tick re-expressed in the newest surface's camera, the frame a replay against the recorded
// surfaces works in (there Model is Camera).
void reexpress(const glm::dmat3& R_NewModel, std::span<FingertipForce> out);

// The fingertip force model. Pure: no threads, no clocks (time comes in), no allocation after
// construction (a new snapshot only moves shared_ptrs; the publisher should keep retired snapshots
// alive a little so the last release happens on its own thread).
class HapticModel {
 public:
  static constexpr int kMaxFingertips = 10;

  explicit HapticModel(const HapticParams& params, int fingertips = 5);

  // One 1 kHz step, in the Model frame: `in` holds the fingertips there, `out` gets the forces
  // there, and each surface is placed by its own R_ModelCamera. `newest` is the newest published
  // snapshot (may be null, may repeat); `in` and `out` hold one entry per fingertip. Never throws.
  // The steps, in order (detail/force_steps.h has each):
  //  1. time step: dt from the clock; backwards or long gaps are counted and integrated as
  //     nominal_period_s / max_tick_s (time_step);
  //  2. surface: a newer frame becomes current, the previous one is kept for the crossfade
  //     (accept_surface), and the current one's age decides freshness;
  //  3. crossfade: the view blends the previous surface into the current over crossfade_s
  //     (crossfade_weight, SurfaceView);
  //  then per fingertip:
  //  4. tracking: the tracker's flag, NaN/Inf, > 1 km or a stale sample is tracking loss
  //     (fingertip_tracked);
  //  5. gain: ramps up over startup_ramp_s, down over fade_out_s (ramp_gain);
  //  6. contact: the god-point proxy (update_proxy: push-out, free move, friction, spring force)
  //     and the fingertip's status; tracking loss holds the last force instead;
  //  7. damping and passivity: virtual damping, the Hannaford/Ryu observer's damping and force
  //     bound (passivity);
  //  8. clamp to max_force_N (clamp_force), then the gain;
  //  9. rate limit: at most max_force_step_N of change per tick (rate_limit);
  // 10. outputs: pressure, shear, the shear along the finger, proxy, normal (write_output).
  TickStatus tick(std::int64_t now_ns, const std::shared_ptr<const Surface>& newest,
                  std::span<const FingertipInput> in, std::span<FingertipForce> out);

  // Forgets proxies, ramps and the observer (e.g. after the operator re-engages).
  void reset();
  // The display was commanded zero force from outside the model (the station's display
  // supervisor, while the station was stopped or hung): the next ticks start from zero, through
  // the rate limit and the start-up ramp, instead of jumping back to the force last output.
  // Proxies and contacts are kept, so the force comes back where it was.
  void restart_output();
  // The display was held at zero for a moment (the link or the tracker silent for tens of ms):
  // the next ticks start from zero through the rate limit only (max_force_step_N a tick), the
  // gain kept, so a brief silence costs a brief dip and never a jump.
  void resume_output();

  const HapticParams& params() const { return params_; }
  const HapticCounters& counters() const { return counters_; }
  int fingertips() const { return fingertips_; }

 private:
  void accept_surface(std::int64_t now_ns, const std::shared_ptr<const Surface>& newest);
  // Steps 4 to 10 for one fingertip.
  void finger_tick(detail::FingerState& f, const detail::SurfaceView& view, bool surface_fresh,
                   std::int64_t now_ns, double dt_s, const FingertipInput& fin, FingertipForce& fo);
  // Step 6 for a tracked fingertip with a surface: proxy, status and the observer's energy.
  // Returns the fingertip's velocity when it has one.
  std::optional<glm::dvec3> contact(detail::FingerState& f, const detail::SurfaceView& view,
                                    bool surface_fresh, const glm::dvec3& x, double dt_s);

  HapticParams params_;
  int fingertips_;
  std::array<detail::FingerState, kMaxFingertips> fingers_{};
  std::shared_ptr<const Surface> current_;
  std::shared_ptr<const Surface> previous_;
  std::int64_t fade_start_ns_ = 0;
  bool has_time_ = false;
  std::int64_t last_ns_ = 0;
  HapticCounters counters_{};
};

}  // namespace telex
