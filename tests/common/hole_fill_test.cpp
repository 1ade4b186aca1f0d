// SPDX-License-Identifier: MIT
// Windowed-mode hole filling: hand-built cases, synthetic ground truth, the real desk frames, ROI.
#include "telex/common/hole_fill.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <string>
#include <vector>

#include "telex/common/synthetic.h"
#include "test_support.h"

namespace telex {
namespace {

TEST(HoleFill, SingleHoleTakesTheMajoritySurface) {
  cv::Mat1w d(5, 5, std::uint16_t{1000});
  // Six pixels of a nearer surface at 700 mm and one outlier: the 1000 mm wall wins by count.
  for (int x = 0; x < 5; ++x) d(0, x) = 700;
  d(1, 0) = 700;
  d(4, 4) = 3000;
  d(2, 2) = 0;
  const auto r = fill_holes_mode(d);
  EXPECT_EQ(r.holes_in, 1u);
  EXPECT_EQ(r.holes_out, 0u);
  EXPECT_EQ(r.passes_run, 1);
  EXPECT_EQ(r.depth_mm(2, 2), 1000);
  // The input is untouched.
  EXPECT_EQ(d(2, 2), 0);
}

TEST(HoleFill, ValueIsTheMeanOfTheWinningBinAndTiesGoNear) {
  // 3x3 window: 4 votes near (1001, 1003, 1005, 1007 -> bin mean 1004), 4 votes far (1500).
  cv::Mat1w d(3, 3, std::uint16_t{1500});
  d(0, 0) = 1001;
  d(0, 1) = 1003;
  d(0, 2) = 1005;
  d(1, 0) = 1007;
  d(1, 1) = 0;
  HoleFillOptions o;
  o.window_px = 3;
  o.bin_mm = 20;
  const auto r = fill_holes_mode(d, o);
  EXPECT_EQ(r.depth_mm(1, 1), 1004);
}

TEST(HoleFill, LaterPassesSeeEarlierFillsAndStopAtTheLimit) {
  // A 12-pixel-wide vertical gap: a 5x5 window closes 2 columns from each side per pass.
  cv::Mat1w d(20, 40, std::uint16_t{900});
  d.colRange(14, 26).setTo(0);
  HoleFillOptions o;
  o.max_passes = 2;
  const auto two = fill_holes_mode(d, o);
  EXPECT_EQ(two.passes_run, 2);
  EXPECT_EQ(two.holes_in, 240u);
  EXPECT_EQ(two.holes_out, 240u - 8u * 20u);
  EXPECT_EQ(count_holes(two.depth_mm), two.holes_out);
  o.max_passes = 16;
  const auto all = fill_holes_mode(d, o);
  EXPECT_EQ(all.passes_run, 3);
  EXPECT_EQ(all.holes_out, 0u);
  EXPECT_EQ(cv::countNonZero(all.depth_mm != 900), 0);
}

TEST(HoleFill, MinValidLeavesSparselySupportedHoles) {
  cv::Mat1w d(9, 9, std::uint16_t{0});
  d(4, 4) = 1200;
  HoleFillOptions o;
  o.min_valid = 2;
  const auto r = fill_holes_mode(d, o);
  EXPECT_EQ(r.holes_out, r.holes_in);
  EXPECT_EQ(r.passes_run, 0);
  o.min_valid = 1;
  const auto r1 = fill_holes_mode(d, o);
  EXPECT_EQ(r1.holes_out, 0u);
  EXPECT_EQ(cv::countNonZero(r1.depth_mm != 1200), 0);
}

TEST(HoleFill, NoHolesIsANoOp) {
  cv::Mat1w d(48, 64, std::uint16_t{1234});
  const auto r = fill_holes_mode(d);
  EXPECT_EQ(r.holes_in, 0u);
  EXPECT_EQ(r.passes_run, 0);
  EXPECT_EQ(cv::norm(r.depth_mm, d, cv::NORM_INF), 0.0);
}

TEST(HoleFill, RejectsBadOptions) {
  const cv::Mat1w d(8, 8, std::uint16_t{0});
  HoleFillOptions o;
  o.window_px = 4;
  EXPECT_THROW(fill_holes_mode(d, o), std::invalid_argument);
  o = {};
  o.bin_mm = 0;
  EXPECT_THROW(fill_holes_mode(d, o), std::invalid_argument);
  EXPECT_THROW(fill_holes_mode(cv::Mat1w()), std::invalid_argument);
  EXPECT_THROW(fill_holes_mode_roi(d, cv::Rect(4, 4, 8, 8)), std::invalid_argument);
}

// Punches isolated holes and 6x6 blocks into a noisy synthetic desk and compares the fills with
// the true depth.
TEST(HoleFill, SyntheticPunchedHolesRmse) {
  const auto r =
      synth::render(synth::Scene::named("desk"), kinect_v1_intrinsics(), synth::SensorModel{}, 7);
  cv::Mat1w punched = r.depth.depth_mm.clone();
  cv::Mat1b mask(punched.size(), std::uint8_t{0});
  std::mt19937 rng(42);
  std::uniform_int_distribution<int> px(3, 636), py(3, 476);
  for (int i = 0; i < 6000; ++i) mask(py(rng), px(rng)) = 1;
  for (int i = 0; i < 150; ++i) mask(cv::Rect(px(rng) - 3, py(rng) - 3, 6, 6)).setTo(1);
  double sq_fill = 0.0, sq_sensor = 0.0;
  std::vector<double> abs_fill, abs_sensor;
  std::size_t n = 0;
  const auto result = fill_holes_mode([&] {
    for (int y = 0; y < punched.rows; ++y)
      for (int x = 0; x < punched.cols; ++x)
        if (mask(y, x) && punched(y, x) != 0)
          punched(y, x) = 0;
        else
          mask(y, x) = 0;  // only pixels that had a measurement count
    return punched;
  }());
  for (int y = 0; y < punched.rows; ++y)
    for (int x = 0; x < punched.cols; ++x) {
      if (!mask(y, x)) continue;
      const double truth_mm = r.true_depth_m(y, x) * 1000.0;
      ASSERT_NE(result.depth_mm(y, x), 0) << x << "," << y;
      sq_fill += std::pow(result.depth_mm(y, x) - truth_mm, 2);
      sq_sensor += std::pow(r.depth.depth_mm(y, x) - truth_mm, 2);
      abs_fill.push_back(std::fabs(result.depth_mm(y, x) - truth_mm));
      abs_sensor.push_back(std::fabs(r.depth.depth_mm(y, x) - truth_mm));
      ++n;
    }
  std::sort(abs_fill.begin(), abs_fill.end());
  std::sort(abs_sensor.begin(), abs_sensor.end());
  const double median_fill = abs_fill[n / 2], median_sensor = abs_sensor[n / 2];
  const double rmse_fill = std::sqrt(sq_fill / n), rmse_sensor = std::sqrt(sq_sensor / n);
  std::printf(
      "punched %zu px: fill RMSE %.2f mm (median |err| %.2f), sensor at the same pixels RMSE %.2f "
      "mm (median %.2f)\n",
      n, rmse_fill, median_fill, rmse_sensor, median_sensor);
  EXPECT_GT(n, 8000u);
  // The fill is a local average of one surface: about as good as the measurement it replaces
  // (the RMSE of both is dominated by the few pixels on object edges).
  EXPECT_LT(rmse_fill, 1.5 * rmse_sensor);
  EXPECT_LT(median_fill, 1.5 * median_sensor + 1.0);
}

TEST(HoleFill, RoiEqualsFullFrameInsideAndInputOutside) {
  const auto r =
      synth::render(synth::Scene::named("box"), kinect_v1_intrinsics(), synth::SensorModel{}, 1);
  cv::Mat1w d = r.depth.depth_mm.clone();
  d(cv::Rect(250, 200, 40, 30)).setTo(0);  // a gap needing several passes
  const auto full = fill_holes_mode(d);
  for (const cv::Rect roi : {cv::Rect(240, 190, 30, 25), cv::Rect(0, 0, 640, 480),
                             cv::Rect(600, 0, 40, 480), cv::Rect(260, 205, 10, 10)}) {
    const auto part = fill_holes_mode_roi(d, roi);
    EXPECT_EQ(cv::norm(part.depth_mm(roi), full.depth_mm(roi), cv::NORM_INF), 0.0) << roi;
    cv::Mat1w outside_in = d.clone(), outside_out = part.depth_mm.clone();
    outside_in(roi).setTo(0);
    outside_out(roi).setTo(0);
    EXPECT_EQ(cv::norm(outside_in, outside_out, cv::NORM_INF), 0.0) << roi;
    EXPECT_EQ(part.holes_in, count_holes(d(roi)));
    EXPECT_EQ(part.holes_out, count_holes(part.depth_mm(roi)));
  }
}

TEST(HoleFill, RealDeskFramesMostlyFilledWithinRange) {
  TELEX_REQUIRE_REAL_DATA();
  for (int i = 0; i < 3; ++i) {
    const auto path =
        telex::test::real_data_dir() / "desk" / ("desk_" + std::to_string(i) + "_depth_mm.png");
    const cv::Mat1w d = cv::imread(path.string(), cv::IMREAD_ANYDEPTH);
    ASSERT_FALSE(d.empty()) << path;
    double lo = 0, hi = 0;
    cv::minMaxLoc(d, nullptr, &hi);
    cv::minMaxLoc(d, &lo, nullptr, nullptr, nullptr, d > 0);
    const auto r = fill_holes_mode(d);
    const double filled_fraction = 1.0 - static_cast<double>(r.holes_out) / r.holes_in;
    std::printf("%s: holes %zu -> %zu (%.2f %% filled) in %d passes\n", path.filename().c_str(),
                r.holes_in, r.holes_out, 100.0 * filled_fraction, r.passes_run);
    EXPECT_GT(r.holes_in, 0.07 * d.total());
    EXPECT_GE(filled_fraction, 0.95);
    double out_lo = 0, out_hi = 0;
    cv::minMaxLoc(r.depth_mm, &out_lo, &out_hi, nullptr, nullptr, r.depth_mm > 0);
    EXPECT_GE(out_lo, lo);
    EXPECT_LE(out_hi, hi);
    // Measured pixels are never changed.
    cv::Mat1w diff;
    cv::absdiff(d, r.depth_mm, diff);
    EXPECT_EQ(cv::countNonZero((diff != 0) & (d > 0)), 0);
  }
}

}  // namespace
}  // namespace telex
