// SPDX-License-Identifier: MIT
// Tests of the synthetic scenes and sensor model against analytic ground truth.
#include "telex/common/synthetic.h"

#include <gtest/gtest.h>

#include <cmath>
#include <glm/geometric.hpp>
#include <map>
#include <numbers>
#include <set>

namespace telex::synth {
namespace {

constexpr double kPi = std::numbers::pi;

glm::dvec3 pixel_ray(const Intrinsics& k, int u, int v) {
  return glm::normalize(glm::dvec3((u - k.cx) / k.fx, (v - k.cy) / k.fy, 1.0));
}

TEST(Synthetic, PlaneDepthEqualsAnalyticZ) {
  const Intrinsics k = kinect_v1_intrinsics();
  const Rendered r = render(Scene::named("plane"), k, SensorModel::ideal());
  ASSERT_EQ(r.depth.depth_mm.size(), cv::Size(640, 480));
  for (int v = 0; v < k.height; ++v)
    for (int u = 0; u < k.width; ++u) {
      ASSERT_NEAR(r.true_depth_m(v, u), 0.8, 1e-6) << u << "," << v;
      ASSERT_EQ(r.depth.depth_mm(v, u), 800) << u << "," << v;
    }
}

TEST(Synthetic, TiltedPlaneDepthEqualsAnalyticZ) {
  const Intrinsics k = kinect_v1_intrinsics();
  const Rendered r = render(Scene::named("tilted"), k, SensorModel::ideal());
  const double a = 35.0 * kPi / 180.0;
  const glm::dvec3 n(std::sin(a), 0, std::cos(a));
  const double d = std::cos(a);  // the plane passes through (0, 0, 1 m)
  for (int v = 0; v < k.height; v += 7)
    for (int u = 0; u < k.width; u += 5) {
      const glm::dvec3 dir = pixel_ray(k, u, v);
      const double z = d / glm::dot(n, dir) * dir.z;
      ASSERT_NEAR(r.true_depth_m(v, u), z, 1e-5 * z) << u << "," << v;
      ASSERT_NEAR(r.depth.depth_mm(v, u), z * 1000.0, 0.5 + 1e-6) << u << "," << v;
      const cv::Vec3f nt = r.true_normals(v, u);
      // Facing the camera: the opposite of the plane normal that points away from it.
      EXPECT_NEAR(nt[0], -n.x, 1e-6);
      EXPECT_NEAR(nt[1], 0.0, 1e-6);
      EXPECT_NEAR(nt[2], -n.z, 1e-6);
    }
}

TEST(Synthetic, SphereNormalsMatchGeometry) {
  const Intrinsics k = kinect_v1_intrinsics(320, 240);
  const Rendered r = render(Scene::named("sphere"), k, SensorModel::ideal());
  const glm::dvec3 c(0, 0, 0.7);
  int on_sphere = 0, on_wall = 0;
  for (int v = 0; v < k.height; ++v)
    for (int u = 0; u < k.width; ++u) {
      const double z = r.true_depth_m(v, u);
      ASSERT_GT(z, 0.0);
      const glm::dvec3 p((u - k.cx) / k.fx * z, (v - k.cy) / k.fy * z, z);
      const cv::Vec3f nt = r.true_normals(v, u);
      EXPECT_NEAR(std::hypot(nt[0], nt[1], nt[2]), 1.0, 1e-5);
      if (r.object_id(v, u) == 0) {
        ++on_sphere;
        EXPECT_NEAR(glm::length(p - c), 0.15, 1e-5);
        const glm::dvec3 expect = (p - c) / 0.15;
        EXPECT_NEAR(nt[0], expect.x, 1e-4);
        EXPECT_NEAR(nt[1], expect.y, 1e-4);
        EXPECT_NEAR(nt[2], expect.z, 1e-4);
      } else {
        ++on_wall;
        EXPECT_NEAR(z, 1.2, 1e-5);
        EXPECT_NEAR(nt[2], -1.0, 1e-6);
      }
    }
  // The sphere's silhouette subtends asin(0.15 / 0.7); its image is roughly a disc of that radius.
  const double radius_px = k.fx * std::tan(std::asin(0.15 / 0.7));
  EXPECT_NEAR(on_sphere, kPi * radius_px * radius_px, 0.03 * kPi * radius_px * radius_px);
  EXPECT_GT(on_wall, 0);
}

TEST(Synthetic, BoxAndCylinderRaycast) {
  Scene s;
  const int box = s.add_box({0, 0, 1.0}, {0.1, 0.2, 0.3});
  const int cyl = s.add_cylinder({0.5, 0, 2.0}, {0, 1, 0}, 0.1, 0.2);
  auto hb = s.raycast({0, 0, 0}, {0, 0, 1});
  ASSERT_TRUE(hb);
  EXPECT_EQ(hb->object_id, box);
  EXPECT_NEAR(hb->t_m, 0.7, 1e-12);
  EXPECT_NEAR(hb->normal_camera.z, -1.0, 1e-12);
  // From the side (origin at x = -1) the box's -x face is hit.
  auto side = s.raycast({-1, 0.1, 1.1}, {1, 0, 0});
  ASSERT_TRUE(side);
  EXPECT_NEAR(side->t_m, 0.9, 1e-12);
  EXPECT_NEAR(side->normal_camera.x, -1.0, 1e-12);
  // Cylinder side, then its top cap from above (y down: the cap at y = -0.2).
  auto hc = s.raycast({0.5, 0, 0}, {0, 0, 1});
  ASSERT_TRUE(hc);
  EXPECT_EQ(hc->object_id, cyl);
  EXPECT_NEAR(hc->t_m, 1.9, 1e-12);
  EXPECT_NEAR(hc->normal_camera.z, -1.0, 1e-12);
  auto cap = s.raycast({0.52, -1.0, 2.0}, {0, 1, 0});
  ASSERT_TRUE(cap);
  EXPECT_NEAR(cap->t_m, 0.8, 1e-12);
  EXPECT_NEAR(cap->normal_camera.y, -1.0, 1e-12);
  EXPECT_FALSE(s.raycast({0, 0, 0}, {0, 0, -1}));
  EXPECT_TRUE(s.blocked({0, 0, 0}, {0, 0, 1}, 0.8));
  EXPECT_FALSE(s.blocked({0, 0, 0}, {0, 0, 1}, 0.6));
  EXPECT_FALSE(s.blocked({0, 0, 0}, {0, 0, 1}, 0.8, box));
}

// Std of (measured - true) over the frontal plane, against the Nguyen sigma at 0.8 m. Incidence
// stays below 60 deg across the image, so sigma is the same everywhere.
double plane_noise_std_mm(const SensorModel& m) {
  const Intrinsics k = kinect_v1_intrinsics();
  double sum = 0, sum2 = 0;
  int n = 0;
  for (std::uint64_t f = 0; f < 2; ++f) {
    const Rendered r = render(Scene::named("plane"), k, m, f);
    for (int v = 0; v < k.height; ++v)
      for (int u = 0; u < k.width; ++u) {
        const std::uint16_t d = r.depth.depth_mm(v, u);
        if (d == 0) continue;
        const double e = d - 800.0;
        sum += e;
        sum2 += e * e;
        ++n;
      }
  }
  const double mean = sum / n;
  return std::sqrt(sum2 / n - mean * mean);
}

TEST(Synthetic, AxialNoiseMatchesNguyenOnPlane) {
  const double sigma_mm = axial_sigma_m(0.8, 0.0) * 1000.0;
  EXPECT_NEAR(sigma_mm, 1.2 + 1.9 * 0.16, 1e-9);
  SensorModel only_axial = SensorModel::ideal();
  only_axial.axial_noise = true;
  EXPECT_NEAR(plane_noise_std_mm(only_axial), sigma_mm, 0.2 * sigma_mm);
  // The full default model (lateral jitter, quantisation, holes) on the same plane.
  EXPECT_NEAR(plane_noise_std_mm(SensorModel{}), sigma_mm, 0.2 * sigma_mm);
  // Without noise the error is only mm rounding.
  EXPECT_LT(plane_noise_std_mm(SensorModel::ideal()), 1e-9);
}

TEST(Synthetic, AxialSigmaGrowsBeyondSixtyDegrees) {
  EXPECT_DOUBLE_EQ(axial_sigma_m(1.0, 0.3), axial_sigma_m(1.0, 1.0));
  EXPECT_GT(axial_sigma_m(1.0, 1.3), axial_sigma_m(1.0, 1.0) * 1.5);
  EXPECT_TRUE(std::isfinite(axial_sigma_m(1.0, kPi / 2)));
}

TEST(Synthetic, QuantisationStepsGrowWithDepthSquared) {
  const Intrinsics k = kinect_v1_intrinsics();
  SensorModel m = SensorModel::ideal();
  m.quantise = true;
  const Rendered r = render(Scene::named("tilted"), k, m);
  std::set<int> values;
  for (int v = 0; v < k.height; ++v)
    for (int u = 0; u < k.width; ++u)
      if (r.depth.depth_mm(v, u)) values.insert(r.depth.depth_mm(v, u));
  ASSERT_GT(values.size(), 50u);
  int checked = 0;
  for (auto it = values.begin(); std::next(it) != values.end(); ++it) {
    const double z_m = *it / 1000.0;
    if (z_m < 0.9) continue;  // below ~2 mm steps, mm rounding dominates
    const double step_mm = 2.9e-3 * z_m * z_m * 1000.0;
    EXPECT_NEAR(*std::next(it) - *it, step_mm, 0.1 * step_mm + 1.0) << "at z " << z_m;
    ++checked;
  }
  EXPECT_GT(checked, 40);
  // And directly: one raw disparity unit is z^2 / 351.3 m.
  const double z = 2.4, raw = depth_m_to_kinect_raw(z);
  EXPECT_NEAR(kinect_raw_to_depth_m(raw + 1) - z, 2.9e-3 * z * z, 0.03 * 2.9e-3 * z * z);
}

TEST(Synthetic, ShadowHolesBesideBoxEdgeOnTheCorrectSide) {
  const Intrinsics k = kinect_v1_intrinsics();
  SensorModel m = SensorModel::ideal();
  m.shadow_holes = true;
  const Rendered r = render(Scene::named("box"), k, m);
  // Projector at +x: the box's left front edge (x = -0.15, z = 0.7) shadows the wall (z = 1.1)
  // between the camera's and the projector's rays over that edge; the right side is lit.
  const double x_proj = m.baseline_m + (-0.15 - m.baseline_m) * 1.1 / 0.7;
  const double x_cam = -0.15 * 1.1 / 0.7;
  const int u_shadow_begin = static_cast<int>(std::ceil(k.fx * x_proj / 1.1 + k.cx));
  const int u_shadow_end = static_cast<int>(std::ceil(k.fx * x_cam / 1.1 + k.cx)) - 1;
  ASSERT_GT(u_shadow_end - u_shadow_begin, 15);
  const int u_box_right = static_cast<int>(std::ceil(k.fx * 0.15 / 0.7 + k.cx));
  for (int v = 200; v < 280; v += 10) {
    for (int u = u_shadow_begin; u <= u_shadow_end; ++u)
      EXPECT_EQ(r.depth.depth_mm(v, u), 0) << u << "," << v;
    EXPECT_NE(r.depth.depth_mm(v, u_shadow_begin - 2), 0);
    for (int u = u_box_right + 1; u < k.width; ++u)
      EXPECT_NE(r.depth.depth_mm(v, u), 0) << u << "," << v;
    EXPECT_EQ(r.depth.depth_mm(v, u_shadow_end + 2), 700);
  }
  // Mirror-image check: a projector on the other side shadows the right edge instead.
  m.baseline_m = -0.075;
  const Rendered l = render(Scene::named("box"), k, m);
  EXPECT_EQ(l.depth.depth_mm(240, u_box_right + 5), 0);
  EXPECT_NE(l.depth.depth_mm(240, (u_shadow_begin + u_shadow_end) / 2), 0);
}

TEST(Synthetic, DeterministicBySeedAndFrame) {
  const Intrinsics k = kinect_v1_intrinsics(320, 240);
  const Scene s = Scene::named("desk");
  SensorModel m;
  const Rendered a = render(s, k, m, 3), b = render(s, k, m, 3), c = render(s, k, m, 4);
  m.seed = 2;
  const Rendered d = render(s, k, m, 3);
  EXPECT_EQ(cv::norm(a.depth.depth_mm, b.depth.depth_mm, cv::NORM_L1), 0.0);
  EXPECT_GT(cv::countNonZero(a.depth.depth_mm != c.depth.depth_mm), 1000);
  EXPECT_GT(cv::countNonZero(a.depth.depth_mm != d.depth.depth_mm), 1000);
  // Ground truth does not depend on the noise seed.
  EXPECT_EQ(cv::norm(a.true_depth_m, d.true_depth_m, cv::NORM_L1), 0.0);
}

TEST(Synthetic, DropoutRateIsHonoured) {
  const Intrinsics k = kinect_v1_intrinsics();
  SensorModel m = SensorModel::ideal();
  m.dropout_rate = 0.05;
  const Rendered r = render(Scene::named("plane"), k, m);
  const double rate = static_cast<double>(count_holes(r.depth.depth_mm)) / (640 * 480);
  EXPECT_NEAR(rate, 0.05, 0.004);
}

TEST(Synthetic, AllNamedScenesRender) {
  const Intrinsics k = kinect_v1_intrinsics(320, 240);
  for (const std::string& name : Scene::names()) {
    SCOPED_TRACE(name);
    const Scene s = Scene::named(name);
    const Rendered r = render(s, k, SensorModel{});
    const double valid = 1.0 - static_cast<double>(count_holes(r.depth.depth_mm)) / (320 * 240);
    EXPECT_GT(valid, 0.6);
    double lo, hi;
    cv::minMaxLoc(r.depth.depth_mm, nullptr, &hi);
    cv::minMaxLoc(r.depth.depth_mm, &lo, nullptr, nullptr, nullptr, r.depth.depth_mm > 0);
    EXPECT_GE(lo, 400);
    EXPECT_LE(hi, 4000);
    EXPECT_EQ(s.animated(), name == "moving");
  }
}

TEST(Synthetic, DeskSeesSeveralObjects) {
  const Intrinsics k = kinect_v1_intrinsics(320, 240);
  const Rendered r = render(Scene::named("desk"), k, SensorModel::ideal());
  std::map<int, int> seen;
  for (int v = 0; v < k.height; ++v)
    for (int u = 0; u < k.width; ++u) ++seen[r.object_id(v, u)];
  // floor, wall, table top, box and mug (legs may hide behind the top).
  EXPECT_GE(seen.size(), 5u);
  for (auto [id, count] : seen) EXPECT_GT(count, 20) << "object " << id;
}

TEST(Synthetic, MovingSceneMovesAndStaticOnesDoNot) {
  const Intrinsics k = kinect_v1_intrinsics(160, 120);
  const Scene moving = Scene::named("moving");
  const Rendered t0 = render(moving.at_time(0.0), k, SensorModel::ideal());
  const Rendered t1 = render(moving.at_time(1.0), k, SensorModel::ideal());
  const Rendered t4 = render(moving.at_time(4.0), k, SensorModel::ideal());  // one period
  EXPECT_GT(cv::countNonZero(t0.depth.depth_mm != t1.depth.depth_mm), 50);
  EXPECT_EQ(cv::countNonZero(t0.depth.depth_mm != t4.depth.depth_mm), 0);
  const Scene desk = Scene::named("desk");
  const Rendered d0 = render(desk.at_time(0.0), k, SensorModel::ideal());
  const Rendered d1 = render(desk.at_time(1.0), k, SensorModel::ideal());
  EXPECT_EQ(cv::countNonZero(d0.depth.depth_mm != d1.depth.depth_mm), 0);
}

TEST(Synthetic, RenderFromDisplacedCamera) {
  const Intrinsics k = kinect_v1_intrinsics(160, 120);
  const Scene s = Scene::named("sphere");
  const Rendered a = render(s, k, SensorModel::ideal());
  const Rendered b = render_from(s, k, {0, 0, 0}, SensorModel::ideal());
  EXPECT_EQ(cv::norm(a.true_depth_m, b.true_depth_m, cv::NORM_L1), 0.0);
  // Moving the camera 0.1 m forward brings the sphere's nearest point to 0.45 m.
  const Rendered c = render_from(s, k, {0, 0, 0.1}, SensorModel::ideal());
  double lo;
  cv::minMaxLoc(c.true_depth_m, &lo);
  EXPECT_NEAR(lo, 0.45, 1e-3);
}

void expect_identical(const Rendered& a, const Rendered& b) {
  EXPECT_EQ(cv::countNonZero(a.depth.depth_mm != b.depth.depth_mm), 0);
  EXPECT_EQ(cv::countNonZero(a.true_depth_m != b.true_depth_m), 0);
  EXPECT_EQ(cv::countNonZero(a.object_id != b.object_id), 0);
  cv::Mat normals_diff = a.true_normals != b.true_normals;
  EXPECT_EQ(cv::countNonZero(normals_diff.reshape(1)), 0);
}

TEST(SyntheticRenderer, IncrementalFramesEqualFullRenders) {
  const Intrinsics k = kinect_v1_intrinsics();
  const Scene moving = Scene::named("moving");
  SensorModel m;
  m.seed = 5;
  Renderer renderer(k, m);
  for (std::uint64_t f = 0; f < 6; ++f) {
    SCOPED_TRACE(f);
    const Scene now = moving.at_time(0.3 * f);  // the ball moves 1-11 cm between frames
    const Rendered inc = renderer.render(now, f);
    expect_identical(inc, render(now, k, m, f));
    if (f == 0) {
      EXPECT_EQ(renderer.last_recast_pixels(), 640u * 480u);
    } else {
      // Only the ball's neighbourhood and its shadow are cast again.
      EXPECT_GT(renderer.last_recast_pixels(), 0u);
      EXPECT_LT(renderer.last_recast_pixels(), 640u * 480u / 4);
    }
  }
  // A different scene is rendered from scratch, and a static one costs no ray casts.
  const Scene box = Scene::named("box");
  expect_identical(renderer.render(box, 9), render(box, k, m, 9));
  EXPECT_EQ(renderer.last_recast_pixels(), 640u * 480u);
  expect_identical(renderer.render(box.at_time(3.0), 10), render(box, k, m, 10));
  EXPECT_EQ(renderer.last_recast_pixels(), 0u);
}

TEST(SyntheticRenderer, ShadowOfAMovingObjectIsUpdated) {
  // A ball that moves across the projector's view of a wall: its shadow must follow it even on
  // wall pixels far from the ball's own image.
  const Intrinsics k = kinect_v1_intrinsics(320, 240);
  Scene s;
  s.add_plane({0, 0, 1}, 1.5);
  const int ball = s.add_sphere({0, 0, 0.5}, 0.05);
  s.set_motion(ball, Motion{{0.2, 0, 0}, 2.0});
  SensorModel m = SensorModel::ideal();
  m.shadow_holes = true;
  Renderer renderer(k, m, {0.01, 0, 0});
  for (double t : {0.0, 0.3, 0.5, 1.2}) {
    const Scene now = s.at_time(t);
    expect_identical(renderer.render(now, 0), render_from(now, k, {0.01, 0, 0}, m, 0));
  }
}

TEST(Synthetic, UnknownNameThrowsWithValidList) {
  try {
    Scene::named("kitchen");
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("kitchen"), std::string::npos);
    for (const auto& n : Scene::names()) EXPECT_NE(msg.find(n), std::string::npos) << n;
  }
}

TEST(Synthetic, RejectsBadInput) {
  SensorModel m;
  m.dropout_rate = 2.0;
  EXPECT_THROW(render(Scene::named("plane"), kinect_v1_intrinsics(), m), std::invalid_argument);
  Intrinsics k = kinect_v1_intrinsics();
  k.width = 0;
  EXPECT_THROW(render(Scene::named("plane"), k, SensorModel{}), std::invalid_argument);
  Scene s = Scene::named("plane");
  EXPECT_THROW(s.set_motion(0, Motion{}), std::invalid_argument);  // planes cannot move
  EXPECT_THROW(s.add_sphere({0, 0, 1}, -1.0), std::invalid_argument);
}

}  // namespace
}  // namespace telex::synth
