// SPDX-License-Identifier: MIT
// Force model: Hooke's law, friction, stick/slip, pop-through, ramps, clamps, rate limits,
// staleness.
#include "telex/haptics/haptic_model.h"

#include <gtest/gtest.h>

#include <cmath>
#include <glm/geometric.hpp>
#include <limits>
#include <vector>

namespace telex {
namespace {

constexpr std::int64_t kMs = 1'000'000;

// Model parameters with every safety stage wide open, to look at the bare contact model.
HapticParams bare() {
  HapticParams p;
  p.stiffness_N_per_m = 500.0;
  p.max_force_N = 1e6;
  p.max_force_step_N = 1e6;
  p.startup_ramp_s = 0.0;
  p.crossfade_s = 0.0;
  p.stale_limit_s = 1e6;  // tests that look at staleness set their own limit
  return p;
}

const Intrinsics kK = kinect_v1_intrinsics(160, 120);

std::shared_ptr<const Surface> wall(double z_m, std::int64_t capture_ns = 0, std::uint64_t id = 1) {
  return std::make_shared<const Surface>(
      make_surface(cv::Mat1f(kK.height, kK.width, static_cast<float>(z_m)), kK, capture_ns, id));
}

// The same snapshot re-published as a new frame (the pixels are shared, not copied).
std::shared_ptr<const Surface> restamp(const std::shared_ptr<const Surface>& s,
                                       std::int64_t capture_ns, std::uint64_t id) {
  auto out = std::make_shared<Surface>(*s);
  out->capture_ns = capture_ns;
  out->frame_id = id;
  return out;
}

// Positions and forces computed against float depth maps carry float rounding.
constexpr double kPosTol = 1e-7;
constexpr double kForceTol = 1e-4;

// One-fingertip driver.
struct Rig {
  explicit Rig(const HapticParams& p) : model(p, 1) {}
  FingertipForce step(const glm::dvec3& p_ModelFingertip,
                      std::shared_ptr<const Surface> s = nullptr, bool tracked = true) {
    if (s) surface = std::move(s);
    now_ns += kMs;
    FingertipInput in;
    in.p_ModelFingertip = p_ModelFingertip;
    in.tracked = tracked;
    FingertipForce out;
    last_status = model.tick(now_ns, surface, std::span(&in, 1), std::span(&out, 1));
    return out;
  }
  // Moves in a straight line over `ticks` ticks and returns the last output.
  FingertipForce move(const glm::dvec3& from, const glm::dvec3& to, int ticks) {
    FingertipForce out;
    for (int i = 1; i <= ticks; ++i) out = step(from + (to - from) * (double(i) / ticks));
    return out;
  }
  HapticModel model;
  std::shared_ptr<const Surface> surface;
  std::int64_t now_ns = 0;
  TickStatus last_status = TickStatus::Ok;
};

TEST(HapticModel, HookesLawOnPlane) {
  HapticParams p = bare();
  p.mu_static = p.mu_dynamic = 0.0;
  Rig rig(p);
  rig.surface = wall(0.8);
  rig.step({0.01, 0.02, 0.75});
  for (double pen : {0.001, 0.004, 0.012}) {
    const FingertipForce f = rig.move({0.01, 0.02, 0.79}, {0.01, 0.02, 0.8 + pen}, 20);
    ASSERT_TRUE(f.contact);
    EXPECT_NEAR(f.penetration_m, pen, kPosTol);
    EXPECT_NEAR(f.normal_force_N, p.stiffness_N_per_m * pen, kForceTol);
    EXPECT_NEAR(f.force_N.z, -p.stiffness_N_per_m * pen, kForceTol);  // pushes toward the camera
    EXPECT_LT(glm::length(f.tangential_force_N), 1e-9);
    EXPECT_NEAR(f.p_ModelProxy.z, 0.8 - p.proxy_epsilon_m, kPosTol);
  }
  const FingertipForce off = rig.move({0.01, 0.02, 0.81}, {0.01, 0.02, 0.7}, 20);
  EXPECT_FALSE(off.contact);
  EXPECT_EQ(glm::length(off.force_N), 0.0);
}

TEST(HapticModel, FrictionOpposesSlidingDirection) {
  HapticParams p = bare();
  p.mu_static = 0.4;
  p.mu_dynamic = 0.3;
  Rig rig(p);
  rig.surface = wall(0.8);
  rig.step({0.0, 0.0, 0.79});
  rig.move({0.0, 0.0, 0.79}, {0.0, 0.0, 0.805}, 10);
  for (const glm::dvec3 dir :
       {glm::dvec3(1, 0, 0), glm::dvec3(0, -1, 0), glm::dvec3(-0.6, 0.8, 0)}) {
    const glm::dvec3 start(0.0, 0.0, 0.805);
    const FingertipForce f = rig.move(start, start + 0.05 * dir, 200);
    ASSERT_TRUE(f.contact);
    EXPECT_TRUE(f.slipping);
    const glm::dvec3 t = f.tangential_force_N;
    // Kinetic friction: opposite to the motion with magnitude mu_d times the normal force.
    EXPECT_GT(glm::dot(glm::normalize(t), -dir), 0.999);
    EXPECT_NEAR(glm::length(t), p.mu_dynamic * f.normal_force_N, kForceTol);
    // The one-direction shear display sees the friction along the finger axis (default -y).
    EXPECT_NEAR(f.shear_along_axis_N, -dir.y * -p.mu_dynamic * f.normal_force_N, kForceTol);
    rig.move(start + 0.05 * dir, start, 200);  // back to the centre for the next direction
  }
}

TEST(HapticModel, StickSlipHysteresis) {
  HapticParams p = bare();
  p.mu_static = 0.5;
  p.mu_dynamic = 0.3;
  Rig rig(p);
  rig.surface = wall(0.8);
  rig.step({0.0, 0.0, 0.79});
  const double pen = 0.01;
  rig.move({0.0, 0.0, 0.79}, {0.0, 0.0, 0.8 + pen}, 10);
  // Sticking: the proxy holds its place while the shear grows up to mu_s * N.
  FingertipForce f = rig.move({0, 0, 0.8 + pen}, {0.004, 0, 0.8 + pen}, 40);
  EXPECT_FALSE(f.slipping);
  EXPECT_NEAR(f.p_ModelProxy.x, 0.0, kPosTol);
  EXPECT_NEAR(glm::length(f.tangential_force_N), 0.4 * f.normal_force_N, kForceTol);
  // Past atan(mu_s): slips, and the shear drops to mu_d * N.
  f = rig.move({0.004, 0, 0.8 + pen}, {0.02, 0, 0.8 + pen}, 100);
  EXPECT_TRUE(f.slipping);
  EXPECT_NEAR(glm::length(f.tangential_force_N), 0.3 * f.normal_force_N, kForceTol);
  // Moving back a little: the angle falls below atan(mu_d) but not below 0.6 atan(mu_d):
  // still slipping (hysteresis), proxy does not move.
  const double proxy_x = f.p_ModelProxy.x;
  const double back_small = pen * (0.3 - std::tan(0.6 * std::atan(0.3))) * 0.5;
  f = rig.move({0.02, 0, 0.8 + pen}, {0.02 - back_small, 0, 0.8 + pen}, 5);
  EXPECT_TRUE(f.slipping);
  EXPECT_NEAR(f.p_ModelProxy.x, proxy_x, kPosTol);
  // Further back, under 0.6 atan(mu_d): sticks again.
  f = rig.move({0.02 - back_small, 0, 0.8 + pen}, {proxy_x + 0.0005, 0, 0.8 + pen}, 20);
  EXPECT_FALSE(f.slipping);
  EXPECT_NEAR(f.p_ModelProxy.x, proxy_x, kPosTol);
}

TEST(HapticModel, NoPopThroughThinObject) {
  // A 3-pixel-wide bar at 0.6 m in front of a wall at 1.5 m.
  cv::Mat1f depth(kK.height, kK.width, 1.5f);
  depth(cv::Rect(79, 0, 3, kK.height)) = 0.6f;
  auto s = std::make_shared<const Surface>(make_surface(depth, kK, 0, 1));
  HapticParams p = bare();
  Rig rig(p);
  rig.surface = s;
  // In one tick from in front of the bar on one side to behind it on the other: a per-pixel
  // test sees free space at both ends; the proxy must catch the bar.
  const glm::dvec3 a = back_project(kK, 70.0, 60.0, 0.59);
  const glm::dvec3 b = back_project(kK, 90.0, 60.0, 0.62);
  rig.step(a);
  const FingertipForce f = rig.step(b);
  ASSERT_TRUE(f.contact);
  EXPECT_NEAR(f.p_ModelProxy.z, 0.6 - p.proxy_epsilon_m, 1e-4);
  EXPECT_LT(f.force_N.z, 0.0);
  // Straight through the bar along the optical axis in big steps: the proxy stays on its face.
  Rig rig2(p);
  rig2.surface = s;
  const glm::dvec3 c = back_project(kK, 80.0, 60.0, 1.0);
  rig2.step({c.x * 0.5, c.y * 0.5, 0.5});
  for (double z : {0.65, 0.8, 1.2, 1.6}) {
    const FingertipForce g = rig2.step({c.x * z, c.y * z, z});
    ASSERT_TRUE(g.contact) << z;
    EXPECT_NEAR(g.p_ModelProxy.z, 0.6 - p.proxy_epsilon_m, 1e-4) << z;
  }
}

TEST(HapticModel, StepEdgeBlocksSidewaysEntry) {
  // Near box face on the left half, far wall on the right: sliding on the wall into the box's
  // side must stop the proxy at the edge, not lift it onto the box face.
  cv::Mat1f depth(kK.height, kK.width, 1.1f);
  depth(cv::Rect(0, 0, 80, kK.height)) = 0.7f;
  HapticParams p = bare();
  p.mu_static = p.mu_dynamic = 0.0;
  Rig rig(p);
  rig.surface = std::make_shared<const Surface>(make_surface(depth, kK, 0, 1));
  const glm::dvec3 a = back_project(kK, 120.0, 60.0, 1.1);
  rig.step(a - glm::dvec3(0, 0, 0.01));
  rig.move(a - glm::dvec3(0, 0, 0.01), a + glm::dvec3(0, 0, 0.005), 10);
  const glm::dvec3 b = a + glm::dvec3(-0.45, 0, 0.005);  // well into the box's columns
  const FingertipForce f = rig.move(a + glm::dvec3(0, 0, 0.005), b, 100);
  ASSERT_TRUE(f.contact);
  EXPECT_GT(f.p_ModelProxy.z, 1.0);  // still on the wall side
  const double edge_x = (79.5 - kK.cx) / kK.fx * 1.1;
  EXPECT_NEAR(f.p_ModelProxy.x, edge_x, 0.01);
  EXPECT_GT(f.force_N.x, 0.0);  // pushed back out of the box's side
}

TEST(HapticModel, StartupRampAndRecovery) {
  HapticParams p = bare();
  p.startup_ramp_s = 0.5;
  p.fade_out_s = 0.1;
  Rig rig(p);
  rig.surface = wall(0.8);
  rig.step({0, 0, 0.79});
  rig.step({0, 0, 0.81});
  // The surface is captured at t = 0 and stays fresh for 0.2 s; re-publish it to keep it fresh.
  FingertipForce f;
  // 2 + 123 ticks at 0.002 per tick.
  for (int i = 0; i < 123; ++i) f = rig.step({0, 0, 0.81}, restamp(rig.surface, rig.now_ns, 2 + i));
  const double full = p.stiffness_N_per_m * 0.01;
  EXPECT_NEAR(f.gain, 0.25, 1e-9);
  EXPECT_NEAR(f.normal_force_N, 0.25 * full, kForceTol);
  for (int i = 0; i < 400; ++i)
    f = rig.step({0, 0, 0.81}, restamp(rig.surface, rig.now_ns, 300 + i));
  EXPECT_NEAR(f.gain, 1.0, 1e-12);
  EXPECT_NEAR(f.normal_force_N, full, kForceTol);
}

TEST(HapticModel, ClampAndRateLimit) {
  HapticParams p = bare();
  p.stiffness_N_per_m = 2000.0;
  p.max_force_N = 3.0;
  p.max_force_step_N = 0.05;
  Rig rig(p);
  rig.surface = wall(0.8);
  rig.step({0, 0, 0.79});
  double prev = 0.0, max_step = 0.0, max_force = 0.0;
  // Teleport 5 cm deep: the raw force is 100 N.
  for (int i = 0; i < 200; ++i) {
    const FingertipForce f = rig.step({0, 0, 0.85});
    const double m = glm::length(f.force_N);
    max_step = std::max(max_step, std::abs(m - prev));
    max_force = std::max(max_force, m);
    prev = m;
  }
  EXPECT_NEAR(max_force, 3.0, 1e-9);
  EXPECT_LE(max_step, 0.05 + 1e-12);
  EXPECT_GT(rig.model.counters().clamped, 0u);
  EXPECT_GT(rig.model.counters().rate_limited, 0u);
  // It takes 60 ticks at 0.05 N per tick to reach 3 N.
  Rig rig2(p);
  rig2.surface = wall(0.8);
  rig2.step({0, 0, 0.79});
  FingertipForce f;
  for (int i = 0; i < 59; ++i) f = rig2.step({0, 0, 0.85});
  EXPECT_NEAR(glm::length(f.force_N), 59 * 0.05, 1e-9);
}

// The display supervisor commanded zero while the station was stopped: the output starts again
// from zero, by the rate limit and the start-up ramp, and returns to the contact's force without
// losing the contact.
TEST(HapticModel, RestartOutputRampsUpFromZeroToTheSameContact) {
  HapticParams p = bare();
  p.max_force_step_N = 0.05;
  p.startup_ramp_s = 0.1;
  Rig rig(p);
  rig.surface = wall(0.8);
  rig.step({0, 0, 0.79});
  FingertipForce f;
  for (int i = 0; i < 300; ++i) f = rig.step({0, 0, 0.81});
  const double full = p.stiffness_N_per_m * 0.01;
  ASSERT_NEAR(f.normal_force_N, full, kForceTol);
  rig.model.restart_output();
  f = rig.step({0, 0, 0.81});
  EXPECT_LE(f.normal_force_N, 0.05 + 1e-12) << "jumped back to the force last output";
  EXPECT_TRUE(f.contact);
  double prev = f.normal_force_N, max_step = 0.0;
  for (int i = 0; i < 300; ++i) {
    f = rig.step({0, 0, 0.81});
    max_step = std::max(max_step, f.normal_force_N - prev);
    EXPECT_GE(f.normal_force_N, prev - 1e-12) << i;
    prev = f.normal_force_N;
  }
  EXPECT_LE(max_step, 0.05 + 1e-12);
  EXPECT_NEAR(f.normal_force_N, full, kForceTol);
  EXPECT_NEAR(f.gain, 1.0, 1e-12);
}

// The station held the display at zero for a link's or a tracker's brief silence: the output
// comes back from zero by the rate limit alone (0.05 N a tick), the gain kept at 1 (no 2 s ramp).
TEST(HapticModel, ResumeOutputComesBackByTheRateLimitWithTheGainKept) {
  HapticParams p = bare();
  p.max_force_step_N = 0.05;
  p.startup_ramp_s = 2.0;
  Rig rig(p);
  rig.surface = wall(0.8);
  rig.step({0, 0, 0.79});
  FingertipForce f;
  for (int i = 0; i < 2500; ++i) f = rig.step({0, 0, 0.81});
  const double full = p.stiffness_N_per_m * 0.01;
  ASSERT_NEAR(f.normal_force_N, full, kForceTol);
  ASSERT_NEAR(f.gain, 1.0, 1e-12);
  rig.model.resume_output();
  f = rig.step({0, 0, 0.81});
  EXPECT_NEAR(f.normal_force_N, 0.05, 1e-12) << "jumped back to the force last output";
  EXPECT_NEAR(f.gain, 1.0, 1e-12);
  // full / 0.05 ticks later it is back (a restart_output would take the 2 s ramp).
  const int ticks = static_cast<int>(std::ceil(full / 0.05));
  for (int i = 1; i < ticks; ++i) f = rig.step({0, 0, 0.81});
  EXPECT_NEAR(f.normal_force_N, full, kForceTol);
}

TEST(HapticModel, StaleSurfaceFadesToZero) {
  HapticParams p = bare();
  p.fade_out_s = 0.05;
  p.stale_limit_s = 0.2;
  Rig rig(p);
  rig.surface = wall(0.8, 0, 1);
  rig.step({0, 0, 0.79});
  FingertipForce f = rig.move({0, 0, 0.79}, {0, 0, 0.81}, 10);
  EXPECT_GT(f.normal_force_N, 4.0);
  // No new frame: after 200 ms the surface is stale and the force fades over 50 ms.
  for (int i = 0; i < 189; ++i) f = rig.step({0, 0, 0.81});
  EXPECT_EQ(f.status, FingertipStatus::Ok);
  EXPECT_GT(f.normal_force_N, 4.0);
  for (int i = 0; i < 60; ++i) f = rig.step({0, 0, 0.81});
  EXPECT_EQ(f.status, FingertipStatus::StaleSurface);
  EXPECT_EQ(glm::length(f.force_N), 0.0);
  EXPECT_GT(rig.model.counters().stale_ticks, 0u);
}

TEST(HapticModel, TrackingLossNanFadesAndRecovers) {
  HapticParams p = bare();
  p.fade_out_s = 0.02;
  p.startup_ramp_s = 0.01;
  Rig rig(p);
  rig.surface = wall(0.8, 0, 1);
  rig.step({0, 0, 0.79});
  FingertipForce f = rig.move({0, 0, 0.79}, {0, 0, 0.81}, 10);
  const double held = f.normal_force_N;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  f = rig.step({nan, 0, 0.81});
  EXPECT_EQ(f.status, FingertipStatus::TrackingLost);
  EXPECT_NEAR(f.normal_force_N, held * (1.0 - 0.05), 1e-9);  // one 1 ms step of a 20 ms fade
  for (int i = 0; i < 30; ++i) f = rig.step({0, std::numeric_limits<double>::infinity(), 0.81});
  EXPECT_EQ(glm::length(f.force_N), 0.0);
  EXPECT_TRUE(std::isfinite(f.p_ModelProxy.x));
  EXPECT_EQ(rig.model.counters().nonfinite_inputs, 31u);
  // Tracking back with the finger still 1 cm deep: the proxy is pushed out gradually.
  f = rig.step({0, 0, 0.81});
  EXPECT_TRUE(f.contact);
  EXPECT_LT(f.penetration_m, 0.001);
  for (int i = 0; i < 60; ++i) f = rig.step({0, 0, 0.81});
  EXPECT_NEAR(f.normal_force_N, held, kForceTol);
}

TEST(HapticModel, HolesAndOutsideImageAreNotContact) {
  cv::Mat1f depth(kK.height, kK.width, 0.8f);
  depth(cv::Rect(60, 40, 40, 40)) = 0.0f;
  Rig rig(bare());
  rig.surface = std::make_shared<const Surface>(make_surface(depth, kK, 0, 1));
  const glm::dvec3 hole = back_project(kK, 80.0, 60.0, 0.9);
  rig.step(hole - glm::dvec3(0, 0, 0.2));
  FingertipForce f = rig.step(hole);
  EXPECT_FALSE(f.contact);
  EXPECT_EQ(f.status, FingertipStatus::Hole);
  // Back out in front of the wall, then out of the image and on beyond the wall's depth.
  rig.step(hole - glm::dvec3(0, 0, 0.4));
  rig.step({5.0, 0.0, 0.5});
  f = rig.step({5.0, 0.0, 0.9});
  EXPECT_FALSE(f.contact);
  EXPECT_EQ(f.status, FingertipStatus::OutsideImage);
  f = rig.step({0.0, 0.0, -0.3});
  EXPECT_EQ(f.status, FingertipStatus::BehindCamera);
  EXPECT_EQ(glm::length(f.force_N), 0.0);
}

TEST(HapticModel, SurfaceJumpPushesProxyOutGradually) {
  HapticParams p = bare();
  p.mu_static = p.mu_dynamic = 0.0;
  p.pushout_speed_m_per_s = 0.1;
  Rig rig(p);
  rig.surface = wall(0.8, 0, 1);
  rig.step({0, 0, 0.79});
  rig.step({0, 0, 0.805});
  // The wall jumps 2 cm toward the camera: without the push-out the force would jump by 10 N.
  FingertipForce f = rig.step({0, 0, 0.805}, wall(0.78, rig.now_ns, 2));
  EXPECT_NEAR(f.normal_force_N, p.stiffness_N_per_m * (0.005 + 0.0001), kForceTol);
  for (int i = 0; i < 300; ++i) f = rig.step({0, 0, 0.805});
  EXPECT_NEAR(f.normal_force_N, p.stiffness_N_per_m * 0.025, kForceTol);
}

TEST(HapticModel, OutOfOrderSurfacesIgnoredAndTimeBackwardsCounted) {
  Rig rig(bare());
  rig.surface = wall(0.8, 0, 5);
  rig.step({0, 0, 0.79});
  rig.step({0, 0, 0.79}, wall(0.5, 0, 3));  // older frame id arriving late
  EXPECT_EQ(rig.model.counters().surfaces_out_of_order, 1u);
  const FingertipForce f = rig.step({0, 0, 0.79});
  EXPECT_FALSE(f.contact);  // the 0.5 m wall was never used
  rig.now_ns -= 10 * kMs;
  rig.step({0, 0, 0.79});
  EXPECT_EQ(rig.last_status, TickStatus::TimeWentBackwards);
  EXPECT_EQ(rig.model.counters().time_backwards, 1u);
  FingertipInput in[2];
  FingertipForce out[1];
  EXPECT_EQ(rig.model.tick(0, rig.surface, std::span(in, 2), std::span(out, 1)),
            TickStatus::BadSpan);
}

TEST(HapticModel, CrossfadeBlendsNewSurfaceOverOneFrame) {
  HapticParams p = bare();
  p.crossfade_s = 0.01;
  p.pushout_speed_m_per_s = 10.0;
  p.mu_static = p.mu_dynamic = 0.0;
  Rig rig(p);
  rig.surface = wall(0.8, 0, 1);
  rig.step({0, 0, 0.79});
  rig.step({0, 0, 0.81});
  FingertipForce f = rig.step({0, 0, 0.81}, wall(0.79, rig.now_ns, 2));
  double prev = f.normal_force_N;
  for (int i = 0; i < 10; ++i) {
    f = rig.step({0, 0, 0.81});
    EXPECT_GE(f.normal_force_N, prev - 1e-9);
    EXPECT_LE(f.normal_force_N - prev, p.stiffness_N_per_m * 0.001 + kForceTol);
    prev = f.normal_force_N;
  }
  EXPECT_NEAR(f.normal_force_N, p.stiffness_N_per_m * 0.02, kForceTol);
}

TEST(HapticModel, RejectsBadParameters) {
  HapticParams p;
  p.stiffness_N_per_m = -1.0;
  try {
    HapticModel m(p);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("stiffness_N_per_m"), std::string::npos);
  }
  EXPECT_THROW(HapticModel(HapticParams{}, 0), std::invalid_argument);
  HapticParams q;
  q.max_force_N = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(HapticModel m(q), std::invalid_argument);
}

}  // namespace
}  // namespace telex

namespace telex {
namespace {

TEST(HapticModel, CrossfadeAcrossResolutionChange) {
  HapticParams p = bare();
  p.crossfade_s = 0.01;
  p.pushout_speed_m_per_s = 10.0;
  p.mu_static = p.mu_dynamic = 0.0;
  Rig rig(p);
  cv::Mat1f old_depth(kK.height, kK.width, 0.9f);
  old_depth(cv::Rect(0, 0, 40, kK.height)) = 0.8f;  // only the left quarter is near
  rig.surface = std::make_shared<const Surface>(make_surface(old_depth, kK, 0, 1));
  // A point off the optical axis, where mixing up the two frames' intrinsics would matter: pixel
  // 20 of the old frame is pixel 81.5 of the new one, and pixel 81.5 of the old frame is far.
  const glm::dvec3 dir = back_project(kK, 20.0, 100.0, 1.0);
  rig.step(dir * 0.75);
  const Intrinsics big = kinect_v1_intrinsics(640, 480);
  cv::Mat1f depth(big.height, big.width, 0.79f);
  depth(cv::Rect(0, 0, 320, 480)) = 0.0f;  // left half of the bigger frame is holes
  FingertipForce f = rig.step(
      dir * 0.75, std::make_shared<const Surface>(make_surface(depth, big, rig.now_ns, 2)));
  // During the fade the fingertip presses in: the new frame has a hole there, so the old frame's
  // wall at 0.8 m must stop it.
  for (int i = 1; i <= 5; ++i) f = rig.step(dir * (0.75 + 0.012 * i));
  EXPECT_TRUE(f.contact);
  EXPECT_NEAR(f.normal_force_N, p.stiffness_N_per_m * 0.01, kForceTol);
}

}  // namespace
}  // namespace telex

namespace telex {
namespace {

TEST(HapticModel, StaleTrackingSampleFadesToZero) {
  HapticParams p = bare();
  p.stale_limit_s = 0.2;
  p.fade_out_s = 0.05;
  HapticModel model(p, 1);
  auto s = wall(0.8, 0, 1);
  FingertipInput in;
  FingertipForce out;
  std::int64_t now = 0;
  auto tick = [&](double z, std::int64_t sample_ns) {
    now += kMs;
    in.p_ModelFingertip = {0, 0, z};
    in.sample_ns = sample_ns;
    model.tick(now, restamp(s, now, static_cast<std::uint64_t>(now / kMs) + 1), std::span(&in, 1),
               std::span(&out, 1));
  };
  tick(0.79, kMs);
  for (int i = 0; i < 10; ++i) tick(0.79 + 0.002 * (i + 1), now + kMs);
  EXPECT_NEAR(out.normal_force_N, p.stiffness_N_per_m * 0.01, kForceTol);
  // The tracker stops: the same pose keeps arriving with its old timestamp.
  const std::int64_t last_sample = now;
  for (int i = 0; i < 200; ++i) tick(0.81, last_sample);
  EXPECT_EQ(out.status, FingertipStatus::Ok);  // 200 ms old: still within the limit
  for (int i = 0; i < 51; ++i) tick(0.81, last_sample);
  EXPECT_EQ(out.status, FingertipStatus::TrackingLost);
  EXPECT_EQ(glm::length(out.force_N), 0.0);
  EXPECT_GT(model.counters().stale_tracking, 0u);
}

}  // namespace
}  // namespace telex
