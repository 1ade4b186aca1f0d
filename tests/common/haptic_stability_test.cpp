// SPDX-License-Identifier: MIT
// The stability suite's criteria on a fast subset: passivity bound, clamps, extreme inputs,
// accuracy.
#include "telex/stability/haptic_stability.h"

#include <gtest/gtest.h>

#include <set>

namespace telex {
namespace {

double metric(const StabilityCaseResult& r, const std::string& name) {
  for (const auto& [k, v] : r.metrics)
    if (k == name) return v;
  ADD_FAILURE() << "no metric " << name << " in " << r.name;
  return 0.0;
}

TEST(HapticStability, GroundedWallAtPassivityBoundSettles) {
  GroundedDevice dev;
  HapticParams p;
  const double bound = p.passive_stiffness_limit(dev.damping_Ns_per_m);
  EXPECT_DOUBLE_EQ(bound, 400.0);
  for (int sub : {1, 20}) {
    dev.substeps = sub;
    const StabilityCaseResult r = grounded_wall_case(bound, false, dev);
    EXPECT_TRUE(r.pass) << r.name << ": " << r.note;
    EXPECT_LT(metric(r, "energy_ratio_end"), 1.0) << r.name;
    EXPECT_EQ(r.nonfinite, 0u);
  }
}

TEST(HapticStability, AboveBoundGrowsUntilClampAndObserverStopsIt) {
  GroundedDevice dev;
  dev.substeps = 20;  // close to the continuous device the bound is about
  const StabilityCaseResult raw = grounded_wall_case(1e4, false, dev);
  EXPECT_GT(metric(raw, "energy_ratio_end"), 1.0) << raw.note;  // limit cycle
  EXPECT_LE(raw.max_force_N, 12.0 + 1e-9);                      // held by the clamp
  EXPECT_EQ(raw.nonfinite, 0u);
  EXPECT_GT(raw.energy_in_J, 0.0);  // the sampled wall generated energy
  const StabilityCaseResult po = grounded_wall_case(1e4, true, dev);
  EXPECT_TRUE(po.pass) << po.note;
  EXPECT_LT(metric(po, "energy_ratio_end"), 1.0);
  EXPECT_GT(metric(po, "observer_active_ticks"), 0.0);
}

TEST(HapticStability, LargestSettlingStiffnessIsAtLeastTheBound) {
  GroundedDevice dev;
  dev.substeps = 20;
  const double k = largest_settling_stiffness(dev);
  EXPECT_GE(k, 400.0);
  // Colgate's bound is sufficient, not necessary, but the measured limit stays within an order.
  EXPECT_LT(k, 4000.0);
}

TEST(HapticStability, CutaneousStiffWallsStayClampedAndRateLimited) {
  for (double k : {100.0, 1e6}) {
    const StabilityCaseResult r = cutaneous_case(k);
    EXPECT_TRUE(r.pass) << r.name << ": " << r.note;
    EXPECT_LE(r.max_force_N, HapticParams{}.max_force_N + 1e-12);
    EXPECT_LE(r.max_force_step_N, HapticParams{}.max_force_step_N + 1e-9);
  }
}

TEST(HapticStability, ExtremeInputsMeetTheirCriteria) {
  const std::vector<StabilityCaseResult> cases = extreme_cases(20'000, 3);
  std::set<std::string> names;
  for (const auto& r : cases) {
    names.insert(r.name);
    EXPECT_TRUE(r.pass) << r.name << ": " << r.note << " (" << r.criteria << ")";
    EXPECT_EQ(r.nonfinite, 0u) << r.name;
    EXPECT_GT(r.ticks, 0u) << r.name;
  }
  for (const char* want :
       {"all-holes", "one-valid-pixel", "depth-0-and-max", "step-edge-1m", "surface-89deg",
        "teleport-1m", "tracker-nan-inf", "outside-image", "surfaces-out-of-order", "stale-surface",
        "time-backwards", "gap-1s", "random-combinations"})
    EXPECT_TRUE(names.count(want)) << want;
}

TEST(HapticStability, AnalyticPlaneAndSphereWithinFivePercent) {
  const std::vector<StabilityCaseResult> cases = accuracy_cases(false);
  ASSERT_EQ(cases.size(), 8u);  // 2 scenes x press/stroke x exact/ideal-mm
  for (const auto& r : cases) {
    EXPECT_TRUE(r.pass) << r.name << ": " << r.note;
    if (r.name.ends_with(" exact")) {
      EXPECT_LE(metric(r, "rms_error_rel_peak"), 0.05) << r.name;
    }
    // Millimetre rounding costs a few percent, never tens of them.
    EXPECT_LE(metric(r, "rms_error_rel_peak"), 0.10) << r.name;
    EXPECT_GT(metric(r, "peak_force_N"), 1.0) << r.name;  // the path really pressed
  }
}

}  // namespace
}  // namespace telex
