// SPDX-License-Identifier: MIT
// Depth bilateral filter: noise reduction, sharp steps, holes, OpenCV agreement, ROI, SIMD =
// scalar.
#include "telex/common/bilateral.h"

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/imgproc.hpp>

#include "telex/common/synthetic.h"

namespace telex {
namespace {

// RMS of (depth - truth) in mm over pixels where both exist and `use` is set.
double rms_error_mm(const cv::Mat1f& depth_m, const cv::Mat1f& truth_m, const cv::Mat1b& use) {
  double sq = 0.0;
  std::size_t n = 0;
  for (int y = 0; y < depth_m.rows; ++y)
    for (int x = 0; x < depth_m.cols; ++x) {
      if (!use(y, x) || depth_m(y, x) <= 0.0f || truth_m(y, x) <= 0.0f) continue;
      sq += std::pow(1000.0 * (depth_m(y, x) - truth_m(y, x)), 2);
      ++n;
    }
  return n ? std::sqrt(sq / n) : 0.0;
}

cv::Mat1f to_m(const cv::Mat1w& mm) {
  cv::Mat1f m;
  mm.convertTo(m, CV_32F, 1e-3);
  return m;
}

TEST(Bilateral, ReducesNoiseOnAPlane) {
  const auto r =
      synth::render(synth::Scene::named("tilted"), kinect_v1_intrinsics(), synth::SensorModel{}, 2);
  const cv::Mat1b all(r.true_depth_m.size(), std::uint8_t{1});
  const double raw = rms_error_mm(to_m(r.depth.depth_mm), r.true_depth_m, all);
  BilateralOptions kinfu;
  kinfu.radius_px = 6;
  const double d5 = rms_error_mm(bilateral_filter_depth(r.depth.depth_mm), r.true_depth_m, all);
  const double d13 =
      rms_error_mm(bilateral_filter_depth(r.depth.depth_mm, kinfu), r.true_depth_m, all);
  BilateralOptions noise;
  noise.sigma_from_noise_model = true;
  const double dn =
      rms_error_mm(bilateral_filter_depth(r.depth.depth_mm, noise), r.true_depth_m, all);
  std::printf("tilted plane RMS error: raw %.2f mm, d=5 %.2f, d=13 %.2f, noise-model d=5 %.2f\n",
              raw, d5, d13, dn);
  EXPECT_LT(d5, 0.7 * raw);
  EXPECT_LT(d13, 0.5 * raw);
  EXPECT_LT(dn, 0.8 * raw);
}

TEST(Bilateral, KeepsStepEdgesSharp) {
  // Box face at 0.7 m before a wall at 1.1 m: ideal depth plus the sensor's axial noise.
  synth::SensorModel s = synth::SensorModel::ideal();
  s.axial_noise = true;
  const auto r = synth::render(synth::Scene::named("box"), kinect_v1_intrinsics(), s, 1);
  BilateralOptions o;
  o.radius_px = 6;
  const cv::Mat1f f = bilateral_filter_depth(r.depth.depth_mm, o);
  cv::Mat1f gauss;
  cv::GaussianBlur(to_m(r.depth.depth_mm), gauss, cv::Size(13, 13), 4.5);
  // Pixels within 3 px of a true step of more than 10 cm.
  cv::Mat1b near_edge(r.true_depth_m.size(), std::uint8_t{0});
  for (int y = 3; y < near_edge.rows - 3; ++y)
    for (int x = 3; x < near_edge.cols - 3; ++x)
      for (int d = -3; d <= 3; ++d)
        if (std::fabs(r.true_depth_m(y, x + d) - r.true_depth_m(y, x)) > 0.1f ||
            std::fabs(r.true_depth_m(y + d, x) - r.true_depth_m(y, x)) > 0.1f)
          near_edge(y, x) = 1;
  ASSERT_GT(cv::countNonZero(near_edge), 1000);
  const double err_bilateral = rms_error_mm(f, r.true_depth_m, near_edge);
  const double err_gauss = rms_error_mm(gauss, r.true_depth_m, near_edge);
  const double err_raw = rms_error_mm(to_m(r.depth.depth_mm), r.true_depth_m, near_edge);
  std::printf("near step edges RMS error: raw %.2f mm, bilateral %.2f, Gaussian %.2f\n", err_raw,
              err_bilateral, err_gauss);
  EXPECT_LT(err_bilateral, 1.5 * err_raw);
  EXPECT_LT(err_bilateral, 0.1 * err_gauss);
}

TEST(Bilateral, HolesNeitherVoteNorGetWritten) {
  cv::Mat1w d(9, 9, std::uint16_t{1000});
  d(4, 4) = 0;
  d(4, 5) = 0;
  d(0, 0) = 0;
  const cv::Mat1f f = bilateral_filter_depth(d);
  EXPECT_EQ(f(4, 4), 0.0f);
  EXPECT_EQ(f(0, 0), 0.0f);
  // A flat 1 m surface stays exactly 1 m next to holes and at the border.
  for (const cv::Point p : {cv::Point(3, 4), cv::Point(6, 4), cv::Point(1, 0), cv::Point(8, 8)})
    EXPECT_NEAR(f(p), 1.0f, 1e-6f) << p;
}

TEST(Bilateral, NeighboursBeyondThreeSigmaAreIgnored) {
  cv::Mat1w d(5, 5, std::uint16_t{1000});
  d(2, 3) = 1091;  // 91 mm > 3 * 30 mm: ignored
  d(2, 1) = 1089;  // 89 mm: votes with a tiny weight
  BilateralOptions o;
  o.radius_px = 1;
  const cv::Mat1f f = bilateral_filter_depth(d, o);
  const double w_space = std::exp(-1.0 / (2 * 4.5 * 4.5));
  const double w = w_space * std::exp(-0.5 * 89.0 * 89.0 / 900.0);
  // The radius-1 disc: centre, two equal 1000 mm neighbours, the 1089 one (the 1091 one is out).
  const double sum_w = 1.0 + 2 * w_space + w;
  const double expected_mm = (1000.0 * (1.0 + 2 * w_space) + 1089.0 * w) / sum_w;
  EXPECT_NEAR(f(2, 2) * 1000.0, expected_mm, 1e-3);
}

TEST(Bilateral, AgreesWithOpenCvOnAHoleFreeFrame) {
  const auto r =
      synth::render(synth::Scene::named("sphere"), kinect_v1_intrinsics(), synth::SensorModel{}, 3);
  cv::Mat1w d = r.depth.depth_mm.clone();
  d.setTo(1500, d == 0);  // OpenCV would average holes in; give it none
  cv::Mat1f d_mm;
  d.convertTo(d_mm, CV_32F);
  for (int diameter : {5, 13}) {
    BilateralOptions o;
    o.radius_px = diameter / 2;
    const cv::Mat1f ours = bilateral_filter_depth(d, o);
    cv::Mat cv_out;
    cv::bilateralFilter(d_mm, cv_out, diameter, 30.0, 4.5, cv::BORDER_REFLECT_101);
    cv::Mat1f diff;
    cv::absdiff(ours * 1000.0f, cv_out, diff);
    // Interior only: OpenCV reflects at the border, ours treats outside as holes.
    const cv::Rect inner(8, 8, d.cols - 16, d.rows - 16);
    const double mean_diff = cv::mean(diff(inner))[0];
    std::printf("d=%d: mean |ours - cv::bilateralFilter| %.4f mm\n", diameter, mean_diff);
    EXPECT_LT(mean_diff, 0.05);
  }
}

TEST(Bilateral, RoiEqualsFullFrame) {
  const auto r =
      synth::render(synth::Scene::named("desk"), kinect_v1_intrinsics(), synth::SensorModel{}, 4);
  for (bool noise_sigma : {false, true}) {
    BilateralOptions o;
    o.radius_px = 6;
    o.sigma_from_noise_model = noise_sigma;
    const cv::Mat1f full = bilateral_filter_depth(r.depth.depth_mm, o);
    for (const cv::Rect roi :
         {cv::Rect(100, 50, 203, 111), cv::Rect(0, 0, 13, 480), cv::Rect(630, 470, 10, 10)}) {
      cv::Mat1f part;
      bilateral_filter_depth_roi(r.depth.depth_mm, roi, part, o);
      ASSERT_EQ(part.size(), roi.size());
      EXPECT_EQ(cv::norm(part, full(roi), cv::NORM_INF), 0.0) << roi;
    }
  }
}

TEST(Bilateral, SimdEqualsScalar) {
  const auto r =
      synth::render(synth::Scene::named("desk"), kinect_v1_intrinsics(), synth::SensorModel{}, 6);
  for (bool noise_sigma : {false, true})
    for (int radius : {1, 2, 6}) {
      BilateralOptions a;
      a.radius_px = radius;
      a.sigma_from_noise_model = noise_sigma;
      BilateralOptions b = a;
      b.allow_simd = false;
      const cv::Mat1f fa = bilateral_filter_depth(r.depth.depth_mm, a);
      const cv::Mat1f fb = bilateral_filter_depth(r.depth.depth_mm, b);
      // Same weights up to float rounding (polynomial exp vs LUT / std::exp) and another
      // summation order (pairs vs taps): within 10 micrometres, far below the sensor's noise.
      EXPECT_LT(cv::norm(fa, fb, cv::NORM_INF), 1e-5) << radius << " " << noise_sigma;
      EXPECT_EQ(cv::countNonZero(fa == 0.0f), cv::countNonZero(fb == 0.0f));
    }
}

TEST(Bilateral, RejectsBadOptions) {
  const cv::Mat1w d(8, 8, std::uint16_t{900});
  BilateralOptions o;
  o.radius_px = 0;
  EXPECT_THROW(bilateral_filter_depth(d, o), std::invalid_argument);
  o = {};
  o.sigma_depth_mm = -1;
  EXPECT_THROW(bilateral_filter_depth(d, o), std::invalid_argument);
  EXPECT_THROW(bilateral_filter_depth(cv::Mat1w()), std::invalid_argument);
  cv::Mat1f out;
  EXPECT_THROW(bilateral_filter_depth_roi(d, cv::Rect(0, 0, 9, 8), out), std::invalid_argument);
}

}  // namespace
}  // namespace telex
