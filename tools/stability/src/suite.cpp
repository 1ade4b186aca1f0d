// SPDX-License-Identifier: MIT
// The stability suite: every case group in one run.
#include "support.h"

namespace telex {

using namespace stability_detail;

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
