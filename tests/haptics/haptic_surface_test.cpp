// SPDX-License-Identifier: MIT
// Surface snapshot queries: bilinear depth refusing holes, nearer-wins edges, normals and
// fallbacks.
#include "telex/haptics/haptic_surface.h"

#include <gtest/gtest.h>

#include <cmath>
#include <glm/geometric.hpp>
#include <limits>

namespace telex {
namespace {

// Depth of the plane n . X = d (n unit, facing the camera) seen through pixel (u, v).
double plane_depth(const Intrinsics& k, const glm::dvec3& n, double d, double u, double v) {
  const glm::dvec3 ray((u - k.cx) / k.fx, (v - k.cy) / k.fy, 1.0);
  return d / glm::dot(n, ray);
}

cv::Mat1f plane_map(const Intrinsics& k, const glm::dvec3& n, double d) {
  cv::Mat1f m(k.height, k.width);
  for (int v = 0; v < k.height; ++v)
    for (int u = 0; u < k.width; ++u) m(v, u) = static_cast<float>(plane_depth(k, n, d, u, v));
  return m;
}

// Plane tilted 35 degrees about y, 1 m in front of the camera on the optical axis.
glm::dvec3 tilted_normal() {
  const double a = 35.0 * M_PI / 180.0;
  return glm::dvec3(std::sin(a), 0.0, -std::cos(a));
}

TEST(HapticSurface, BilinearDepthMatchesAnalyticTiltedPlane) {
  const Intrinsics k = kinect_v1_intrinsics(160, 120);
  const glm::dvec3 n = tilted_normal();
  const double d = glm::dot(n, glm::dvec3(0, 0, 1.0));
  const Surface s = make_surface(plane_map(k, n, d), k, 0, 1);
  for (double u : {10.25, 50.5, 80.0, 120.75}) {
    for (double v : {5.5, 60.0, 100.25}) {
      const auto z = depth_at(s, u, v);
      ASSERT_TRUE(z.has_value());
      // Depth of a plane is not bilinear in pixels, but within a pixel the error is tiny.
      EXPECT_NEAR(*z, plane_depth(k, n, d, u, v), 2e-4) << u << "," << v;
    }
  }
}

TEST(HapticSurface, RefusesHolesAndOutOfImage) {
  const Intrinsics k = kinect_v1_intrinsics(64, 48);
  cv::Mat1f depth(k.height, k.width, 0.8f);
  depth(20, 30) = 0.0f;
  const Surface s = make_surface(depth, k, 0, 1);
  EXPECT_FALSE(depth_at(s, 30.2, 20.1).has_value());  // nearest pixel is the hole
  EXPECT_TRUE(depth_at(s, 30.7, 20.1).has_value());   // nearest pixel valid, hole weight dropped
  EXPECT_NEAR(*depth_at(s, 30.7, 20.1), 0.8, 1e-6);
  EXPECT_FALSE(depth_at(s, -1.0, 10.0).has_value());
  EXPECT_FALSE(depth_at(s, 10.0, 48.0).has_value());
  LocalPlane pl;
  EXPECT_EQ(local_plane(s, {0.0, 0.0, -0.1}, pl), SurfaceQuery::BehindCamera);
  EXPECT_EQ(local_plane(s, {5.0, 0.0, 0.5}, pl), SurfaceQuery::OutsideImage);
  const glm::dvec3 on_hole = back_project(k, 30, 20, 0.7);
  EXPECT_EQ(local_plane(s, on_hole, pl), SurfaceQuery::Hole);
}

TEST(HapticSurface, NearerSurfaceWinsAcrossStep) {
  const Intrinsics k = kinect_v1_intrinsics(64, 48);
  cv::Mat1f depth(k.height, k.width, 1.5f);
  depth(cv::Rect(0, 0, 32, 48)) = 0.5f;  // near half on the left
  const Surface s = make_surface(depth, k, 0, 1);
  // Between column 31 (near) and 32 (far), nearest pixel far: still the near surface, never 1.0.
  const auto z = depth_at(s, 31.9, 10.0);
  ASSERT_TRUE(z.has_value());
  EXPECT_NEAR(*z, 0.5, 1e-6);
  EXPECT_NEAR(*depth_at(s, 34.0, 10.0), 1.5, 1e-6);
  // Normals at the edge column use the one-sided difference on their own side: still frontal.
  const cv::Vec3f n_near = s.normals(10, 31), n_far = s.normals(10, 32);
  EXPECT_NEAR(n_near[2], -1.0f, 1e-4f);
  EXPECT_NEAR(n_far[2], -1.0f, 1e-4f);
}

TEST(HapticSurface, NormalsFromDepthMatchTiltedPlane) {
  const Intrinsics k = kinect_v1_intrinsics(160, 120);
  const glm::dvec3 n = tilted_normal();
  const cv::Mat3f normals =
      normals_from_depth(plane_map(k, n, glm::dot(n, glm::dvec3(0, 0, 1))), k);
  double worst_rad = 0.0;
  for (int v = 0; v < k.height; ++v)
    for (int u = 0; u < k.width; ++u) {
      const cv::Vec3f m = normals(v, u);
      const double c = glm::dot(glm::dvec3(m[0], m[1], m[2]), n);
      worst_rad = std::max(worst_rad, std::acos(std::min(1.0, c)));
    }
  EXPECT_LT(worst_rad, 2e-3);
}

TEST(HapticSurface, PlaneFitFallbackWhenNormalsMissing) {
  const Intrinsics k = kinect_v1_intrinsics(160, 120);
  const glm::dvec3 n = tilted_normal();
  const double d = glm::dot(n, glm::dvec3(0, 0, 1));
  // Supplied normals all zero: every query must fall back to the neighbourhood fit.
  cv::Mat3f zeros(k.height, k.width, cv::Vec3f(0, 0, 0));
  const Surface s = make_surface(plane_map(k, n, d), k, 0, 1, zeros);
  LocalPlane pl;
  const glm::dvec3 p = back_project(k, 70.3, 40.6, plane_depth(k, n, d, 70.3, 40.6) + 0.01);
  ASSERT_EQ(local_plane(s, p, pl), SurfaceQuery::Ok);
  EXPECT_TRUE(pl.normal_fallback);
  EXPECT_GT(glm::dot(pl.normal_Camera, n), std::cos(2e-3));
  EXPECT_NEAR(glm::dot(n, pl.p_CameraQ), d, 2e-4);
}

TEST(HapticSurface, LonePixelFallsBackToViewRay) {
  const Intrinsics k = kinect_v1_intrinsics(64, 48);
  cv::Mat1f depth(k.height, k.width, 0.0f);
  depth(24, 40) = 0.9f;
  const Surface s = make_surface(depth, k, 0, 1);
  LocalPlane pl;
  ASSERT_EQ(local_plane(s, back_project(k, 40.1, 24.2, 1.0), pl), SurfaceQuery::Ok);
  EXPECT_TRUE(pl.normal_fallback);
  EXPECT_NEAR(glm::length(pl.normal_Camera), 1.0, 1e-9);
  EXPECT_LT(glm::dot(pl.normal_Camera, pl.p_CameraQ), 0.0);
}

TEST(HapticSurface, MakeSurfaceSanitisesAndValidates) {
  const Intrinsics k = kinect_v1_intrinsics(64, 48);
  cv::Mat1f depth(k.height, k.width, 0.8f);
  depth(1, 1) = std::numeric_limits<float>::quiet_NaN();
  depth(1, 2) = std::numeric_limits<float>::infinity();
  depth(1, 3) = -1.0f;
  depth(1, 4) = 1e20f;
  const Surface s = make_surface(depth, k, 5, 7);
  for (int u = 1; u <= 4; ++u) EXPECT_EQ(s.depth_m(1, u), 0.0f) << u;
  EXPECT_EQ(s.capture_ns, 5);
  EXPECT_EQ(s.frame_id, 7u);
  // The snapshot owns its pixels: the caller's buffer may be reused at once.
  depth.setTo(0.1f);
  EXPECT_EQ(s.depth_m(10, 10), 0.8f);
  try {
    make_surface(cv::Mat1f(10, 10, 1.0f), k, 0, 0);
    FAIL() << "size mismatch accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("intrinsics"), std::string::npos) << e.what();
  }
  EXPECT_THROW(make_surface(cv::Mat1f(), k, 0, 0), std::invalid_argument);
  EXPECT_THROW(make_surface(depth, k, 0, 0, cv::Mat3f(3, 3)), std::invalid_argument);
}

}  // namespace
}  // namespace telex
