// SPDX-License-Identifier: MIT
// The stability suite's criteria on a fast subset: passivity bound, clamps, extreme inputs,
// accuracy.
#include "telex/stability/haptic_stability.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <glm/geometric.hpp>
#include <set>
#include <stdexcept>

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

// The same cases checked here from their ticks, not from the suite's verdict: each case's claim
// recomputed from what the model was given and what it answered.
const StabilityCaseResult& find_case(const std::vector<StabilityCaseResult>& all,
                                     const std::string& name) {
  for (const auto& r : all)
    if (r.name == name) return r;
  throw std::runtime_error("no case " + name);
}

bool finite(const glm::dvec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

TEST(HapticStability, ExtremeCasesHoldTheirPropertiesCheckedFromTheirTicks) {
  const HapticParams p;  // every extreme case runs the defaults
  const std::vector<StabilityCaseResult> all = extreme_cases(20'000, 3, /*with_trace=*/true);
  // Every case: finite outputs, |F| within the clamp, |dF| within the rate limit per tick.
  for (const auto& r : all) {
    ASSERT_GT(r.trace.size(), 10u) << r.name;
    glm::dvec3 prev(0.0);
    for (std::size_t i = 0; i < r.trace.size(); ++i) {
      const auto& o = r.trace[i].out;
      ASSERT_TRUE(finite(o.force_N) && finite(o.p_ModelProxy) && std::isfinite(o.normal_force_N))
          << r.name << " tick " << i;
      ASSERT_LE(glm::length(o.force_N), p.max_force_N + 1e-9) << r.name << " tick " << i;
      ASSERT_LE(glm::length(o.force_N - prev), p.max_force_step_N + 1e-9)
          << r.name << " tick " << i;
      prev = o.force_N;
    }
  }
  const auto never_touched = [](const StabilityCaseResult& r) {
    for (const auto& t : r.trace)
      if (t.out.contact || glm::length(t.out.force_N) != 0.0) return false;
    return true;
  };
  EXPECT_TRUE(never_touched(find_case(all, "all-holes")));
  EXPECT_TRUE(never_touched(find_case(all, "outside-image")));
  {
    // A late frame at 0.6 m would put the fingertip (0.7 m) 10 cm inside it: never felt.
    EXPECT_TRUE(never_touched(find_case(all, "surfaces-out-of-order")));
  }
  {
    // One valid pixel at 0.8 m, pressed 2 cm into along its ray. A lone sample has no
    // neighbours for a normal, so it is a fronto-parallel plane patch: Hooke's force
    // k x 0.02 m = 8 N at the default k = 400 N/m, clamped to max_force_N, pointing back along
    // the ray, at the end of the press (before the slide).
    const auto& r = find_case(all, "one-valid-pixel");
    std::size_t end = 0;
    while (end < r.trace.size() && r.trace[end].p_ModelFingertip.z < 0.82 - 1e-9) ++end;
    ASSERT_LT(end, r.trace.size());
    const glm::dvec3 x = r.trace[end].p_ModelFingertip;
    const glm::dvec3 f = r.trace[end].out.force_N;
    const double hooke = std::min(p.stiffness_N_per_m * 0.02, p.max_force_N);
    EXPECT_NEAR(glm::length(f), hooke, 1e-6);
    EXPECT_GT(glm::dot(glm::normalize(f), -glm::normalize(x)), std::cos(1.0 * M_PI / 180.0))
        << "the force points back along the pixel's ray";
  }
  {
    // Over a 1 m step edge and back in contact: the proxy never crosses to the near side.
    const auto& r = find_case(all, "step-edge-1m");
    EXPECT_GT(r.trace.back().out.p_ModelProxy.z, 1.0);
  }
  {
    // A 1 m jump into a wall at 0.8 m: the proxy stays in front of it while the finger is inside.
    const auto& r = find_case(all, "teleport-1m");
    int inside = 0;
    for (const auto& t : r.trace)
      if (t.p_ModelFingertip.z > 1.7) {
        ++inside;
        EXPECT_LT(t.out.p_ModelProxy.z, 0.8 + 1e-6);
      }
    EXPECT_GT(inside, 200);
    EXPECT_FALSE(r.trace.back().out.contact);
  }
  {
    // NaN/Inf from the tracker mid-contact: the force falls at the fade rate and is zero within
    // fade_out_s of the first bad sample, never rising meanwhile.
    const auto& r = find_case(all, "tracker-nan-inf");
    std::size_t bad = 0;
    while (bad < r.trace.size() && finite(r.trace[bad].p_ModelFingertip)) ++bad;
    ASSERT_LT(bad, r.trace.size());
    const double at_bad = bad ? glm::length(r.trace[bad - 1].out.force_N) : 0.0;
    EXPECT_GT(at_bad, 0.5) << "the case must be in contact when tracking breaks";
    const auto fade_ticks = static_cast<std::size_t>(std::ceil(p.fade_out_s / 1e-3)) + 1;
    for (std::size_t i = bad; i < r.trace.size(); ++i) {
      const double f = glm::length(r.trace[i].out.force_N);
      EXPECT_LE(f, glm::length(r.trace[i - 1].out.force_N) + 1e-12) << "tick " << i;
      if (i >= bad + fade_ticks) {
        EXPECT_EQ(f, 0.0) << "tick " << i;
      }
    }
  }
  {
    // The stream stops mid-contact: zero within fade_out_s of the last fresh tick
    // (stale_limit_s after the last frame).
    const auto& r = find_case(all, "stale-surface");
    std::int64_t last_fresh_ns = 0;
    for (const auto& t : r.trace)
      if (t.out.status != FingertipStatus::StaleSurface) last_fresh_ns = t.t_ns;
    bool pressed = false;
    for (const auto& t : r.trace) {
      pressed |= glm::length(t.out.force_N) > 1.0;
      if (t.t_ns > last_fresh_ns + static_cast<std::int64_t>((p.fade_out_s + 2e-3) * 1e9)) {
        EXPECT_EQ(glm::length(t.out.force_N), 0.0) << t.t_ns;
      }
    }
    EXPECT_TRUE(pressed);
  }
  {
    // Time going backwards: ten backwards steps were given; outputs stay finite (above).
    const auto& r = find_case(all, "time-backwards");
    EXPECT_EQ(
        std::count_if(r.trace.begin(), r.trace.end(), [](const auto& t) { return t.dt_ns < 0; }),
        10);
  }
  {
    const auto& r = find_case(all, "gap-1s");
    EXPECT_EQ(std::count_if(r.trace.begin(), r.trace.end(),
                            [](const auto& t) { return t.dt_ns >= 1'000'000'000; }),
              1);
  }
  EXPECT_EQ(find_case(all, "random-combinations").trace.size(), 20'000u);
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
