// SPDX-License-Identifier: MIT
// The force path's steps one at a time (detail/force_steps.h): time step, crossfade, tracking,
// gain, the proxy's push-out, free move, friction, slide and spring, passivity, clamp, rate limit,
// outputs; and the Model frame (a turned surface gives the same force, turned).
#include "telex/haptics/detail/force_steps.h"
#include "telex/haptics/haptic_model.h"

#include <gtest/gtest.h>

#include <cmath>
#include <glm/geometric.hpp>
#include <limits>

namespace telex::detail {
namespace {

constexpr std::int64_t kMs = 1'000'000;
const Intrinsics kK = kinect_v1_intrinsics(160, 120);

Surface wall(double z_m, std::uint64_t id = 1) {
  return make_surface(cv::Mat1f(kK.height, kK.width, static_cast<float>(z_m)), kK, 0, id);
}

// A near box (z = near_m) over the image's right half, in front of a far wall.
Surface box_on_wall(double far_m, double near_m) {
  cv::Mat1f d(kK.height, kK.width, static_cast<float>(far_m));
  d(cv::Rect(kK.width / 2, 0, kK.width / 2, kK.height)) = static_cast<float>(near_m);
  return make_surface(d, kK, 0, 1);
}

glm::dmat3 rot_y(double a) {
  return glm::dmat3(std::cos(a), 0.0, -std::sin(a), 0.0, 1.0, 0.0, std::sin(a), 0.0, std::cos(a));
}

SurfaceView view_of(const Surface& s) {
  SurfaceView v;
  v.cur = &s;
  return v;
}

void expect_near3(const glm::dvec3& a, const glm::dvec3& b, double tol) {
  EXPECT_NEAR(a.x, b.x, tol);
  EXPECT_NEAR(a.y, b.y, tol);
  EXPECT_NEAR(a.z, b.z, tol);
}

TEST(ForceSteps, TimeStepCountsBackwardsAndLongGaps) {
  HapticParams p;
  HapticCounters c;
  TimeStep t = time_step(false, 0, 5 * kMs, p, c);
  EXPECT_EQ(t.dt_s, p.nominal_period_s);  // first tick: no interval yet
  t = time_step(true, 5 * kMs, 7 * kMs, p, c);
  EXPECT_NEAR(t.dt_s, 2e-3, 1e-15);
  EXPECT_EQ(t.status, TickStatus::Ok);
  t = time_step(true, 7 * kMs, 7 * kMs, p, c);
  EXPECT_EQ(t.status, TickStatus::TimeWentBackwards);
  EXPECT_EQ(t.dt_s, p.nominal_period_s);
  t = time_step(true, 7 * kMs, 500 * kMs, p, c);
  EXPECT_EQ(t.status, TickStatus::LongGap);
  EXPECT_EQ(t.dt_s, p.max_tick_s);
  EXPECT_EQ(c.time_backwards, 1u);
  EXPECT_EQ(c.long_gaps, 1u);
}

TEST(ForceSteps, CrossfadeBlendsTheTwoSurfaces) {
  EXPECT_DOUBLE_EQ(crossfade_weight(0.25, 1.0), 0.25);
  EXPECT_EQ(crossfade_weight(-1.0, 1.0), 0.0);
  EXPECT_EQ(crossfade_weight(3.0, 1.0), 1.0);

  const Surface near = wall(1.0, 2), far = wall(2.0, 1);
  SurfaceView v = view_of(near);
  v.prev = &far;
  v.alpha = 0.25;  // a quarter of the way from the far wall to the near one
  ModelPlane pl;
  ASSERT_EQ(v.plane({0.0, 0.0, 1.5}, pl), SurfaceQuery::Ok);
  EXPECT_NEAR(pl.p_ModelQ.z, 1.75, 1e-6);
  double d = 0.0, z = 0.0;
  ASSERT_TRUE(v.behind({0.0, 0.0, 1.9}, d, z));
  EXPECT_NEAR(z, 1.75, 1e-6);
  EXPECT_NEAR(d, 0.15, 1e-6);
  EXPECT_TRUE(v.inside({0.0, 0.0, 1.9}));
  EXPECT_FALSE(v.inside({0.0, 0.0, 1.6}));
}

TEST(ForceSteps, SurfaceViewAnswersInTheModelFrame) {
  Surface s = wall(1.0);
  s.R_ModelCamera = rot_y(0.3);
  const SurfaceView v = view_of(s);
  ModelPlane pl;
  // A point straight ahead of the turned camera, 5 cm in front of the wall.
  ASSERT_EQ(v.plane(s.R_ModelCamera * glm::dvec3(0.0, 0.0, 0.95), pl), SurfaceQuery::Ok);
  expect_near3(pl.p_ModelQ, s.R_ModelCamera * glm::dvec3(0.0, 0.0, 1.0), 1e-6);
  expect_near3(pl.normal_Model, s.R_ModelCamera * glm::dvec3(0.0, 0.0, -1.0), 1e-6);
  // The same point in the Model frame unturned is elsewhere on the wall: not on the camera's axis.
  ASSERT_EQ(v.plane({0.0, 0.0, 0.95}, pl), SurfaceQuery::Ok);
  EXPECT_GT(glm::length(pl.p_ModelQ - s.R_ModelCamera * glm::dvec3(0.0, 0.0, 1.0)), 0.1);
}

TEST(ForceSteps, TrackingRejectsFlagNanFarAndStaleSamples) {
  HapticParams p;
  HapticCounters c;
  bool finite = false;
  FingertipInput in;
  in.p_ModelFingertip = {0.0, 0.0, 0.5};
  EXPECT_TRUE(fingertip_tracked(in, 0, p, c, finite));
  EXPECT_TRUE(finite);
  in.tracked = false;
  EXPECT_FALSE(fingertip_tracked(in, 0, p, c, finite));
  in.tracked = true;
  in.p_ModelFingertip.y = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(fingertip_tracked(in, 0, p, c, finite));
  EXPECT_FALSE(finite);
  EXPECT_EQ(c.nonfinite_inputs, 1u);
  in.p_ModelFingertip = {0.0, 2e3, 0.5};  // > 1 km
  EXPECT_FALSE(fingertip_tracked(in, 0, p, c, finite));
  EXPECT_TRUE(finite);
  in.p_ModelFingertip = {0.0, 0.0, 0.5};
  in.sample_ns = 0;
  EXPECT_FALSE(fingertip_tracked(in, 1000 * kMs, p, c, finite));  // 1 s old, limit 0.2 s
  EXPECT_EQ(c.stale_tracking, 1u);
  EXPECT_TRUE(fingertip_tracked(in, 100 * kMs, p, c, finite));
}

TEST(ForceSteps, GainRampsUpAndFadesAtTheirRates) {
  HapticParams p;
  p.startup_ramp_s = 2.0;
  p.fade_out_s = 0.1;
  EXPECT_DOUBLE_EQ(ramp_gain(0.0, 1.0, p, 0.5), 0.25);
  EXPECT_DOUBLE_EQ(ramp_gain(0.9, 1.0, p, 0.5), 1.0);  // never past the target
  EXPECT_DOUBLE_EQ(ramp_gain(1.0, 0.0, p, 0.05), 0.5);
  EXPECT_DOUBLE_EQ(ramp_gain(0.5, 0.5, p, 0.05), 0.5);
  p.startup_ramp_s = 0.0;  // disabled: at once
  EXPECT_DOUBLE_EQ(ramp_gain(0.0, 1.0, p, 1e-3), 1.0);
}

TEST(ForceSteps, PushOutMovesAProxyUnderAJumpedSurfaceAtBoundedSpeed) {
  HapticParams p;
  p.pushout_speed_m_per_s = 0.5;
  const Surface s = wall(0.8);
  const SurfaceView v = view_of(s);
  FingerState f;
  f.has_proxy = true;
  f.p_ModelProxy = {0.0, 0.0, 0.85};  // 5 cm behind the wall that jumped towards the camera
  const glm::dvec3 x(0.0, 0.0, 0.9);
  ModelPlane pl;
  ASSERT_TRUE(push_out(f, v, x, p, 1e-3, pl));
  EXPECT_NEAR(f.p_ModelProxy.z, 0.85 - 0.5e-3, 1e-9);  // 0.5 mm in one 1 ms tick
  EXPECT_TRUE(f.contact);
  EXPECT_NEAR(f.penetration_m, 0.9 - f.p_ModelProxy.z - p.proxy_epsilon_m, 1e-9);
  EXPECT_NEAR(f.raw_force_N.z, -p.stiffness_N_per_m * f.penetration_m, 1e-6);
  // A proxy just under the surface comes out in one step: the step goes on to the constraints.
  f.p_ModelProxy = {0.0, 0.0, 0.8 + 1e-4};
  EXPECT_FALSE(push_out(f, v, x, p, 1e-3, pl));
  EXPECT_NEAR(f.p_ModelProxy.z, 0.8 - p.proxy_epsilon_m, 1e-6);
}

TEST(ForceSteps, MoveFreeStopsOnTheSurfaceOrAtAStepEdge) {
  const double eps = HapticParams{}.proxy_epsilon_m;
  const Surface s = wall(0.8);
  const SurfaceView v = view_of(s);
  FingerState f;
  f.p_ModelProxy = {0.0, 0.0, 0.5};
  move_free(f, v, {0.0, 0.0, 0.7}, false, eps);  // nothing in the way
  EXPECT_FALSE(f.contact);
  expect_near3(f.p_ModelProxy, {0.0, 0.0, 0.7}, 0.0);
  move_free(f, v, {0.0, 0.0, 0.9}, false, eps);  // through the wall: stops on it
  EXPECT_TRUE(f.contact);
  EXPECT_FALSE(f.side_contact);
  EXPECT_NEAR(f.p_ModelProxy.z, 0.8 - eps, 1e-6);

  // Sliding on the far wall into the near box's side: held at the edge, a side contact.
  const Surface b = box_on_wall(1.2, 0.8);
  const SurfaceView vb = view_of(b);
  FingerState g;
  g.p_ModelProxy = {-0.1, 0.0, 1.15};
  move_free(g, vb, {0.1, 0.0, 1.15}, false, eps);
  EXPECT_TRUE(g.contact);
  EXPECT_TRUE(g.side_contact);
  EXPECT_LT(g.p_ModelProxy.x, 0.02);  // the edge: image column 80 at 1.15 m
}

TEST(ForceSteps, FrictionSticksInsideTheConeAndSlipsWithHysteresis) {
  const glm::dvec3 n(0.0, 0.0, -1.0);
  const double mu_s = 0.5, mu_d = 0.3, hyst = 0.6;
  auto dp = [&](double theta) { return glm::dvec3(std::sin(theta), 0.0, -std::cos(theta)); };
  EXPECT_FALSE(slip_state(false, dp(0.9 * std::atan(mu_s)), n, mu_s, mu_d, hyst));
  EXPECT_TRUE(slip_state(false, dp(1.1 * std::atan(mu_s)), n, mu_s, mu_d, hyst));
  // Once slipping, it slips on until the angle falls below hyst * atan(mu_d).
  EXPECT_TRUE(slip_state(true, dp(0.7 * std::atan(mu_d)), n, mu_s, mu_d, hyst));
  EXPECT_FALSE(slip_state(true, dp(0.5 * std::atan(mu_d)), n, mu_s, mu_d, hyst));
  EXPECT_TRUE(slip_state(false, dp(0.0), n, 0.2, 0.3, hyst));  // mu_d > mu_s: always slipping

  const glm::dvec3 goal(0.0, 0.0, 0.8);
  expect_near3(friction_target({0.001, 0.0, 0.8}, goal, 0.002), {0.001, 0.0, 0.8}, 0.0);
  expect_near3(friction_target({0.004, 0.0, 0.8}, goal, 0.002), {0.002, 0.0, 0.8}, 1e-15);
}

TEST(ForceSteps, SlideSticksThenDragsTheProxyAlongTheSurface) {
  HapticParams p;
  p.mu_static = 0.5;
  p.mu_dynamic = 0.3;
  const double eps = p.proxy_epsilon_m;
  const Surface s = wall(0.8);
  const SurfaceView v = view_of(s);
  FingerState f;
  f.has_proxy = true;
  f.contact = true;
  f.p_ModelProxy = {0.0, 0.0, 0.8 - eps};
  ModelPlane pl;
  ASSERT_EQ(v.plane(f.p_ModelProxy, pl), SurfaceQuery::Ok);
  // 1 cm deep, 2 mm aside: inside the 5 mm static circle, the proxy stays.
  glm::dvec3 x(0.002, 0.0, 0.81);
  ASSERT_TRUE(slide(f, v, x, glm::dot(pl.normal_Model, x - pl.p_ModelQ), p, true, pl));
  EXPECT_FALSE(f.slipping);
  EXPECT_NEAR(f.p_ModelProxy.x, 0.0, 1e-9);
  // 2 cm aside: slips and is dragged to the 3 mm dynamic circle's rim behind the device.
  x = {0.02, 0.0, 0.81};
  ASSERT_TRUE(slide(f, v, x, glm::dot(pl.normal_Model, x - pl.p_ModelQ), p, true, pl));
  EXPECT_TRUE(f.slipping);
  EXPECT_NEAR(f.p_ModelProxy.x, 0.02 - 0.3 * 0.01, 1e-6);
  EXPECT_NEAR(f.p_ModelProxy.z, 0.8 - eps, 1e-6);
}

TEST(ForceSteps, SpringForceFromTheSurfaceOrAlongTheStepEdge) {
  HapticParams p;
  p.stiffness_N_per_m = 400.0;
  const Surface s = wall(0.8);
  const SurfaceView v = view_of(s);
  const ModelPlane none;
  FingerState f;
  f.contact = true;
  f.p_ModelProxy = {0.0, 0.0, 0.8 - p.proxy_epsilon_m};
  spring_force(f, v, {0.0, 0.0, 0.81}, p, none);
  EXPECT_NEAR(f.penetration_m, 0.01, 1e-6);  // eps adds no bias
  expect_near3(f.raw_force_N, {0.0, 0.0, -4.0}, 1e-3);
  f.side_contact = true;
  f.p_ModelProxy = {-0.01, 0.0, 0.81};
  spring_force(f, v, {0.0, 0.0, 0.81}, p, none);
  expect_near3(f.raw_force_N, {-4.0, 0.0, 0.0}, 1e-9);
  expect_near3(f.normal_Model, {-1.0, 0.0, 0.0}, 1e-12);
  f.contact = false;
  spring_force(f, v, {0.0, 0.0, 0.81}, p, none);
  EXPECT_EQ(glm::length(f.raw_force_N), 0.0);
  EXPECT_EQ(f.penetration_m, 0.0);
}

TEST(ForceSteps, PassivityDampsAndBoundsWhatTheContactHasNotAbsorbed) {
  HapticParams p;
  p.virtual_damping_Ns_per_m = 1.0;
  HapticCounters c;
  const glm::dvec3 v(0.0, 0.0, 0.1);  // moving into the wall at 0.1 m/s
  // Observer off: virtual damping only.
  expect_near3(passivity({0.0, 0.0, -2.0}, v, -1.0, 1e-3, p, c), {0.0, 0.0, -2.1}, 1e-12);
  EXPECT_EQ(c.observer_active, 0u);
  p.passivity_observer = true;
  p.virtual_damping_Ns_per_m = 0.0;
  p.max_observer_damping_Ns_per_m = 20.0;
  // Energy generated (E < 0): damping -E / (T v^2), capped at 20 Ns/m.
  expect_near3(passivity({0.0, 0.0, -2.0}, v, -1e-5, 1e-3, p, c), {0.0, 0.0, -2.1}, 1e-12);
  expect_near3(passivity({0.0, 0.0, -2.0}, v, -1.0, 1e-3, p, c), {0.0, 0.0, -4.0}, 1e-12);
  EXPECT_EQ(c.observer_active, 2u);
  // Moving out of the wall (along the force) with 1e-4 J absorbed: at most E / (T |v|) = 1 N
  // along the motion.
  expect_near3(passivity({0.0, 0.0, -2.0}, -v, 1e-4, 1e-3, p, c), {0.0, 0.0, -1.0}, 1e-12);
  EXPECT_EQ(c.observer_active, 3u);
}

TEST(ForceSteps, ClampLimitsTheMagnitudeAndKeepsTheDirection) {
  HapticCounters c;
  const glm::dvec3 f = clamp_force({3.0, 0.0, -4.0}, 3.3, c);  // 5 N over a 3.3 N limit
  EXPECT_NEAR(glm::length(f), 3.3, 1e-12);
  expect_near3(f / 3.3, glm::dvec3(0.6, 0.0, -0.8), 1e-12);
  EXPECT_EQ(c.clamped, 1u);
  expect_near3(clamp_force({1.0, 0.0, 0.0}, 3.3, c), {1.0, 0.0, 0.0}, 0.0);
  EXPECT_EQ(c.clamped, 1u);
}

TEST(ForceSteps, RateLimitBoundsTheChangePerTick) {
  HapticCounters c;
  const glm::dvec3 last(0.0, 0.0, -1.0);
  const glm::dvec3 f = rate_limit({0.0, 0.0, -3.0}, last, 0.05, c);
  EXPECT_NEAR(glm::length(f - last), 0.05, 1e-12);
  expect_near3(f, {0.0, 0.0, -1.05}, 1e-12);
  EXPECT_EQ(c.rate_limited, 1u);
  expect_near3(rate_limit({0.0, 0.0, -1.2}, last, 0.05, c), {0.0, 0.0, -1.05}, 1e-12);
  EXPECT_EQ(c.rate_limited, 2u);
  expect_near3(rate_limit({0.0, 0.01, -1.0}, last, 0.05, c), {0.0, 0.01, -1.0}, 0.0);
  EXPECT_EQ(c.rate_limited, 2u);
}

TEST(ForceSteps, OutputsSplitTheForceAlongTheNormalAndTheFinger) {
  FingerState f;
  f.contact = true;
  f.normal_Model = {0.0, 0.0, -1.0};
  f.p_ModelProxy = {0.01, 0.0, 0.8};
  f.gain = 0.5;
  FingertipForce out;
  write_output({0.3, 0.4, -2.0}, f, {0.0, -1.0, 0.5}, true, out);
  EXPECT_NEAR(out.normal_force_N, 2.0, 1e-12);
  expect_near3(out.tangential_force_N, {0.3, 0.4, 0.0}, 1e-12);
  EXPECT_NEAR(out.shear_along_axis_N, -0.4, 1e-12);  // the axis projected on the plane: -y
  expect_near3(out.p_ModelProxy, f.p_ModelProxy, 0.0);
  EXPECT_EQ(out.gain, 0.5);
  write_output({0.3, 0.4, -2.0}, f, {0.0, -1.0, 0.5}, false, out);  // axis not finite
  EXPECT_EQ(out.shear_along_axis_N, 0.0);
}

// The whole tick in a turned frame: a surface whose camera is turned in the Model frame and a
// fingertip given there feel the force of the unturned case, turned.
TEST(ForceSteps, TickWorksInTheModelFrame) {
  HapticParams p;
  p.startup_ramp_s = 0.0;
  p.max_force_step_N = 1e6;
  p.crossfade_s = 0.0;
  p.stale_limit_s = 1e6;
  p.max_force_N = 1e3;
  const glm::dmat3 R =
      rot_y(0.4) * glm::dmat3(glm::dvec3(1, 0, 0), glm::dvec3(0, std::cos(0.2), std::sin(0.2)),
                              glm::dvec3(0, -std::sin(0.2), std::cos(0.2)));
  auto plain = std::make_shared<const Surface>(wall(0.8));
  auto turned_s = std::make_shared<Surface>(wall(0.8));
  turned_s->R_ModelCamera = R;
  const std::shared_ptr<const Surface> turned = turned_s;
  HapticModel a(p, 1), b(p, 1);
  FingertipForce fa, fb;
  for (int i = 1; i <= 50; ++i) {
    FingertipInput ia, ib;
    ia.p_ModelFingertip = {0.01, -0.02, 0.7 + 0.0024 * i};  // presses 2 cm into the wall
    ib.p_ModelFingertip = R * ia.p_ModelFingertip;
    ib.axis_Model = R * ia.axis_Model;
    a.tick(i * kMs, plain, std::span(&ia, 1), std::span(&fa, 1));
    b.tick(i * kMs, turned, std::span(&ib, 1), std::span(&fb, 1));
  }
  ASSERT_TRUE(fa.contact);
  ASSERT_TRUE(fb.contact);
  EXPECT_NEAR(fa.normal_force_N, 0.02 * p.stiffness_N_per_m, 0.05);
  expect_near3(fb.force_N, R * fa.force_N, 1e-6);
  expect_near3(fb.p_ModelProxy, R * fa.p_ModelProxy, 1e-9);
  expect_near3(fb.normal_Model, R * fa.normal_Model, 1e-9);
  EXPECT_NEAR(fb.shear_along_axis_N, fa.shear_along_axis_N, 1e-6);
  // And re-expressed in the surface's camera, the turned tick is the plain one.
  reexpress(glm::transpose(R), std::span(&fb, 1));
  expect_near3(fb.force_N, fa.force_N, 1e-6);
  expect_near3(fb.p_ModelProxy, fa.p_ModelProxy, 1e-9);
}

}  // namespace
}  // namespace telex::detail
