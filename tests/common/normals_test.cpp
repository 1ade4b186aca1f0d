// SPDX-License-Identifier: MIT
// Normal maps: accuracy against analytic truth and OpenCV FALS, invalid pixels, ROI, SIMD = scalar.
#include "telex/common/normals.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <opencv2/rgbd.hpp>
#include <vector>

#include "telex/common/bilateral.h"
#include "telex/common/colorize.h"
#include "telex/common/depth_image.h"
#include "telex/common/synthetic.h"

namespace telex {
namespace {

struct AngleStats {
  double mean_rad = 0.0;
  double p95_rad = 0.0;
  std::size_t count = 0;
};

bool is_valid(const cv::Vec3f& n) {
  return std::isfinite(n[0]) && std::isfinite(n[1]) && std::isfinite(n[2]) &&
         (n[0] != 0.0f || n[1] != 0.0f || n[2] != 0.0f);
}

// Angular error of `n` against `truth` over the pixels where `use` is set.
AngleStats angle_error(const cv::Mat3f& n, const cv::Mat3f& truth, const cv::Mat1b& use) {
  std::vector<double> e;
  for (int y = 0; y < n.rows; ++y)
    for (int x = 0; x < n.cols; ++x) {
      if (!use(y, x)) continue;
      const cv::Vec3f a = n(y, x), b = truth(y, x);
      const double c =
          std::clamp(static_cast<double>(a.dot(b)) / cv::norm(a) / cv::norm(b), -1.0, 1.0);
      e.push_back(std::acos(c));
    }
  AngleStats s;
  s.count = e.size();
  if (e.empty()) return s;
  double sum = 0.0;
  for (double v : e) sum += v;
  s.mean_rad = sum / e.size();
  std::sort(e.begin(), e.end());
  s.p95_rad = e[static_cast<std::size_t>(0.95 * (e.size() - 1))];
  return s;
}

cv::Mat3f fals_normals(const cv::Mat1f& depth_m, const Intrinsics& k) {
  const cv::Mat K = (cv::Mat_<float>(3, 3) << k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1);
  cv::Mat points;
  cv::rgbd::depthTo3d(depth_m, K, points);
  cv::rgbd::RgbdNormals fals(depth_m.rows, depth_m.cols, CV_32F, K, 5,
                             cv::rgbd::RgbdNormals::RGBD_NORMALS_METHOD_FALS);
  cv::Mat out;
  fals(points, out);
  cv::Mat3f n = out;
  // FALS does not orient its normals; flip them to face the camera like ours and the truth.
  for (int y = 0; y < n.rows; ++y)
    for (int x = 0; x < n.cols; ++x) {
      cv::Vec3f& v = n(y, x);
      const cv::Vec3f ray((x - k.cx) / k.fx, (y - k.cy) / k.fy, 1.0f);
      if (v.dot(ray) > 0) v = -v;
    }
  return n;
}

// Pixels with a true surface, away (4 px) from true depth discontinuities and the image border,
// and valid in every map given.
cv::Mat1b common_mask(const synth::Rendered& r, const std::vector<const cv::Mat3f*>& maps) {
  cv::Mat1b surface = r.true_depth_m > 0.0f;
  cv::Mat1b edge(r.true_depth_m.size(), std::uint8_t{0});
  for (int y = 0; y < edge.rows; ++y)
    for (int x = 0; x < edge.cols; ++x) {
      const float z = r.true_depth_m(y, x);
      if (z <= 0.0f) continue;
      if (x + 1 < edge.cols && std::fabs(r.true_depth_m(y, x + 1) - z) > 0.03f * z)
        edge(y, x) = 255;
      if (y + 1 < edge.rows && std::fabs(r.true_depth_m(y + 1, x) - z) > 0.03f * z)
        edge(y, x) = 255;
    }
  cv::dilate(edge, edge, cv::Mat(), cv::Point(-1, -1), 4);
  cv::Mat1b use = surface & ~edge;
  use.rowRange(0, 4).setTo(0);
  use.rowRange(use.rows - 4, use.rows).setTo(0);
  use.colRange(0, 4).setTo(0);
  use.colRange(use.cols - 4, use.cols).setTo(0);
  for (int y = 0; y < use.rows; ++y)
    for (int x = 0; x < use.cols; ++x)
      for (const cv::Mat3f* m : maps)
        if (use(y, x) && !is_valid((*m)(y, x))) use(y, x) = 0;
  return use;
}

synth::Rendered noisy(const char* scene, std::uint64_t frame = 0) {
  return synth::render(synth::Scene::named(scene), kinect_v1_intrinsics(), synth::SensorModel{},
                       frame);
}

TEST(Normals, ExactOnNoiseFreeTiltedPlane) {
  // Float ground-truth depth, no quantisation: only the method's own error remains.
  const auto r = synth::render(synth::Scene::named("tilted"), kinect_v1_intrinsics(),
                               synth::SensorModel::ideal());
  for (int k : {0, 2}) {
    NormalOptions o;
    o.smooth_radius_px = k;
    const cv::Mat3f n = compute_normals(r.true_depth_m, kinect_v1_intrinsics(), o);
    const AngleStats s = angle_error(n, r.true_normals, common_mask(r, {&n}));
    EXPECT_GT(s.count, 100000u);
    EXPECT_LT(s.mean_rad, 1e-3) << "k=" << k;
    EXPECT_LT(s.p95_rad, 2e-3) << "k=" << k;
  }
}

TEST(Normals, NoisyPlaneAndSphereNoWorseThanFals) {
  for (const char* scene : {"plane", "tilted", "sphere"}) {
    const auto r = noisy(scene);
    const cv::Mat1f depth_m = depth_m_from_mm(r.depth.depth_mm);
    const Intrinsics& k = r.depth.intrinsics;
    const cv::Mat3f ours = compute_normals(depth_m, k);
    const cv::Mat3f ours_bilateral = compute_normals(bilateral_filter_depth(r.depth.depth_mm), k);
    NormalOptions plain;
    plain.smooth_radius_px = 0;
    const cv::Mat3f central = compute_normals(depth_m, k, plain);
    const cv::Mat3f fals = fals_normals(depth_m, k);
    const cv::Mat1b use = common_mask(r, {&ours, &ours_bilateral, &central, &fals});
    const AngleStats s_ours = angle_error(ours, r.true_normals, use);
    const AngleStats s_bil = angle_error(ours_bilateral, r.true_normals, use);
    const AngleStats s_central = angle_error(central, r.true_normals, use);
    const AngleStats s_fals = angle_error(fals, r.true_normals, use);
    std::printf(
        "%-7s n=%zu mean/p95 rad: ours %.4f/%.4f  ours+bilateral %.4f/%.4f  central %.4f/%.4f  "
        "FALS %.4f/%.4f\n",
        scene, s_ours.count, s_ours.mean_rad, s_ours.p95_rad, s_bil.mean_rad, s_bil.p95_rad,
        s_central.mean_rad, s_central.p95_rad, s_fals.mean_rad, s_fals.p95_rad);
    ASSERT_GT(s_ours.count, 20000u) << scene;
    EXPECT_LE(s_ours.mean_rad, s_fals.mean_rad) << scene;
    EXPECT_LE(s_bil.mean_rad, s_fals.mean_rad) << scene;
  }
}

TEST(Normals, FacingTheCameraAndUnitLength) {
  const auto r = noisy("sphere");
  const Intrinsics& k = r.depth.intrinsics;
  const cv::Mat3f n = compute_normals(depth_m_from_mm(r.depth.depth_mm), k);
  std::size_t valid = 0;
  for (int y = 0; y < n.rows; ++y)
    for (int x = 0; x < n.cols; ++x) {
      const cv::Vec3f v = n(y, x);
      if (!is_valid(v)) continue;
      ++valid;
      const cv::Vec3f ray((x - k.cx) / k.fx, (y - k.cy) / k.fy, 1.0f);
      ASSERT_LT(v.dot(ray), 0.0f) << x << "," << y;
      ASSERT_NEAR(cv::norm(v), 1.0, 1e-5);
    }
  EXPECT_GT(valid, 200000u);
}

TEST(Normals, InvalidAtHolesAndAcrossDiscontinuities) {
  // A 0.8 m wall with a 0.5 m square in front of it (a step of 0.3 m) and one hole.
  cv::Mat1f d(60, 80, 0.8f);
  d(cv::Rect(30, 20, 20, 20)).setTo(0.5f);
  d(10, 10) = 0.0f;
  d(12, 60) = std::numeric_limits<float>::quiet_NaN();
  const Intrinsics k = kinect_v1_intrinsics(80, 60);
  const cv::Mat3f n = compute_normals(d, k);
  EXPECT_FALSE(is_valid(n(10, 10)));
  EXPECT_FALSE(is_valid(n(12, 60)));
  // Neighbours of the hole fall back to one-sided differences and stay valid.
  EXPECT_TRUE(is_valid(n(10, 11)));
  EXPECT_TRUE(is_valid(n(9, 10)));
  // Pixels on each side of the step use the side they are on: valid and exactly frontal-ish.
  for (const cv::Point p : {cv::Point(29, 30), cv::Point(30, 30), cv::Point(49, 30),
                            cv::Point(50, 30), cv::Point(40, 19), cv::Point(40, 20)}) {
    ASSERT_TRUE(is_valid(n(p))) << p;
    const cv::Vec3f ray((p.x - k.cx) / k.fx, (p.y - k.cy) / k.fy, 1.0f);
    // A fronto-parallel plane's normal is (0, 0, -1) exactly.
    EXPECT_NEAR(n(p)[2], -1.0f, 1e-6) << p;
  }
  // A one-pixel-wide sliver between two discontinuities has no x derivative: invalid.
  cv::Mat1f s(20, 20, 1.0f);
  s.col(10).setTo(0.6f);
  const cv::Mat3f ns = compute_normals(s, kinect_v1_intrinsics(20, 20));
  for (int y = 0; y < 20; ++y) EXPECT_FALSE(is_valid(ns(y, 10))) << y;
  EXPECT_TRUE(is_valid(ns(10, 9)));
}

TEST(Normals, RoiEqualsFullFrame) {
  const auto r = noisy("desk", 3);
  const cv::Mat1f d = depth_m_from_mm(r.depth.depth_mm);
  const cv::Mat3f full = compute_normals(d, r.depth.intrinsics);
  for (const cv::Rect roi : {cv::Rect(100, 80, 200, 150), cv::Rect(0, 0, 37, 29),
                             cv::Rect(600, 400, 40, 80), cv::Rect(0, 0, 640, 480)}) {
    cv::Mat3f part;
    compute_normals_roi(d, r.depth.intrinsics, roi, part);
    ASSERT_EQ(part.size(), roi.size());
    EXPECT_EQ(cv::norm(part, full(roi), cv::NORM_INF), 0.0) << roi;
  }
}

TEST(Normals, SimdEqualsScalar) {
  for (int k : {0, 1, 2, 3}) {
    const auto r = noisy("desk", 5);
    const cv::Mat1f d = depth_m_from_mm(r.depth.depth_mm);
    NormalOptions a, b;
    a.smooth_radius_px = b.smooth_radius_px = k;
    b.allow_simd = false;
    const cv::Mat3f na = compute_normals(d, r.depth.intrinsics, a);
    const cv::Mat3f nb = compute_normals(d, r.depth.intrinsics, b);
    EXPECT_EQ(cv::norm(na, nb, cv::NORM_INF), 0.0) << "k=" << k;
  }
}

TEST(Normals, ColourVisualisation) {
  cv::Mat3f n(1, 3);
  n(0, 0) = cv::Vec3f(0, 0, -1);
  n(0, 1) = cv::Vec3f(0, 0, 0);
  n(0, 2) = cv::Vec3f(1, 0, 0);
  const cv::Mat3b bgr = colorize_normals(n);     // B = z, G = y, R = x
  EXPECT_EQ(bgr(0, 0), cv::Vec3b(0, 128, 128));  // (0+1)/2*255 = 127.5 rounds to 128
  EXPECT_EQ(bgr(0, 1), cv::Vec3b(0, 0, 0));
  EXPECT_EQ(bgr(0, 2), cv::Vec3b(128, 128, 255));
}

TEST(Normals, RejectsBadInput) {
  const cv::Mat1f d(10, 10, 1.0f);
  NormalOptions o;
  o.smooth_radius_px = -1;
  EXPECT_THROW(compute_normals(d, kinect_v1_intrinsics(10, 10), o), std::invalid_argument);
  EXPECT_THROW(compute_normals(cv::Mat1f(), kinect_v1_intrinsics()), std::invalid_argument);
  cv::Mat3f out;
  EXPECT_THROW(compute_normals_roi(d, kinect_v1_intrinsics(10, 10), cv::Rect(5, 5, 10, 10), out),
               std::invalid_argument);
}

}  // namespace
}  // namespace telex
