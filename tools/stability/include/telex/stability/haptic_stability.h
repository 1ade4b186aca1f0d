// SPDX-License-Identifier: MIT
// Stability and accuracy suite of the haptic model: stiff walls, extreme inputs, analytic surfaces.
// A test of the daemons' code, so it lives with the tools (`telex stability`), not in common/.
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "telex/haptics/haptic_model.h"

namespace telex {

// One haptic tick of a case as the model saw and answered it (recorded on request, so a test can
// check each case's property without trusting the suite's verdict).
struct StabilityTick {
  std::int64_t t_ns = 0;
  std::int64_t dt_ns = 0;
  glm::dvec3 p_ModelFingertip{0.0};
  bool tracked = false;
  FingertipForce out;
};

struct StabilityCaseResult {
  std::string name;
  std::string group;  // stiffness-cutaneous | stiffness-grounded | passivity | extreme | accuracy
  bool pass = false;
  double max_force_N = 0.0;       // largest |F| output over the case
  double max_force_step_N = 0.0;  // largest |F(t) - F(t - 1 tick)|
  double energy_in_J = 0.0;       // net work of the rendered force on a grounded device (0 if none)
  std::uint64_t nonfinite = 0;    // NaN/Inf values seen in any output field
  std::uint64_t ticks = 0;
  std::string criteria;  // what "pass" means for this case, printed with the result
  std::string note;      // what happened
  std::vector<std::pair<std::string, double>> metrics;  // case-specific figures
  std::vector<StabilityTick> trace;                     // every tick, when asked for
};

// A grounded haptic device: a mass-damper pushed into the wall by the operator's hand.
struct GroundedDevice {
  double mass_kg = 0.05;
  double damping_Ns_per_m = 0.2;  // b: the passivity bound at 1 kHz is 2 b / T = 400 N/m
  double hand_force_N = 0.5;      // constant push into the wall
  double approach_speed_m_per_s = 0.1;
  // Semi-implicit Euler steps per 1 kHz haptic tick (the force is held between ticks). 1 is the
  // plain 1 kHz simulation; more approximates the continuous device Colgate's bound is about.
  int substeps = 1;
  double duration_s = 3.0;
};

// Grounded device against a flat wall rendered as a depth map, stiffness `k`. The energy figure
// is the excess mechanical energy (kinetic + wall + hand potential above the resting minimum) at
// the end relative to the start: below 1 means the contact settled.
StabilityCaseResult grounded_wall_case(double k_N_per_m, bool passivity_observer,
                                       const GroundedDevice& device = {});

// Largest stiffness on a quarter-octave grid from 100 N/m up to 1e6 N/m below which every
// grounded run settles, with the observer off; -1 when even 100 N/m does not settle.
double largest_settling_stiffness(const GroundedDevice& device);

// Cutaneous (ungrounded) display: a scripted fingertip press and stroke on a plane that is
// re-rendered at 30 Hz; the finger does not move under the force.
StabilityCaseResult cutaneous_case(double k_N_per_m);

// Extreme inputs, each checked against the common criteria (no NaN/Inf, |F| <= clamp, per-tick
// change <= rate limit) plus its own. `random_ticks` sets the size of the randomised case.
// With `with_trace`, each result carries its ticks.
std::vector<StabilityCaseResult> extreme_cases(std::uint64_t random_ticks, std::uint64_t seed = 1,
                                               bool with_trace = false);

// RMS force error against the analytic force for a press and a stroke on the synthetic "tilted"
// plane and "sphere" scenes: on the exact (noise-free) ray-cast depth the error must stay within
// 5 % of the peak force; the ideal sensor (exact depth rounded to mm) and, with
// `with_sensor_noise`, the Kinect-like sensor model are reported, not judged.
std::vector<StabilityCaseResult> accuracy_cases(bool with_sensor_noise = true);

struct StabilityOptions {
  std::uint64_t random_ticks = 1'000'000;
  std::uint64_t seed = 1;
};

// Everything above: the suite `telex stability` prints.
std::vector<StabilityCaseResult> run_stability_suite(const StabilityOptions& options = {});

}  // namespace telex
