// SPDX-License-Identifier: MIT
// The shared ROI fill: how a region widens (margin, tile alignment, image border) and that the
// widened regions equal a full-frame fill bit for bit while the rest of the output stays untouched.
#include <gtest/gtest.h>

#include <random>
#include <stdexcept>
#include <vector>

#include "telex/common/hole_fill.h"

namespace telex {
namespace {

cv::Mat1w holey(unsigned seed) {
  std::mt19937 rng(seed);
  cv::Mat1w d(240, 320);
  for (int y = 0; y < d.rows; ++y)
    for (int x = 0; x < d.cols; ++x) d(y, x) = static_cast<std::uint16_t>(800 + x + (y > 120) * 90);
  std::uniform_int_distribution<int> px(0, 319), py(0, 239), size(1, 14);
  for (int i = 0; i < 150; ++i)
    d(cv::Rect(px(rng), py(rng), size(rng), size(rng)) & cv::Rect(0, 0, 320, 240)).setTo(0);
  return d;
}

TEST(RoiFill, WidensByMarginThenToWholeTilesClippedToTheImage) {
  const cv::Size image(320, 240);
  EXPECT_EQ(widen_roi({10, 20, 30, 40}, image, {}), cv::Rect(10, 20, 30, 40));
  EXPECT_EQ(widen_roi({10, 20, 30, 40}, image, {3, {1, 1}}), cv::Rect(7, 17, 36, 46));
  // Tiles of 80x60: (10,20)-(40,60) covers the first tile only; one pixel more reaches the next.
  EXPECT_EQ(widen_roi({10, 20, 30, 40}, image, {0, {80, 60}}), cv::Rect(0, 0, 80, 60));
  EXPECT_EQ(widen_roi({10, 20, 30, 41}, image, {0, {80, 60}}), cv::Rect(0, 0, 80, 120));
  // A margin that crosses a tile border takes the neighbouring tile.
  EXPECT_EQ(widen_roi({81, 61, 10, 10}, image, {2, {80, 60}}), cv::Rect(0, 0, 160, 120));
  // Clipped at the border, before and after widening; outside: empty.
  EXPECT_EQ(widen_roi({-5, -5, 10, 10}, image, {2, {1, 1}}), cv::Rect(0, 0, 7, 7));
  EXPECT_EQ(widen_roi({300, 230, 50, 50}, image, {4, {80, 60}}), cv::Rect(240, 180, 80, 60));
  EXPECT_TRUE(widen_roi({400, 10, 10, 10}, image, {4, {80, 60}}).empty());
  EXPECT_THROW(widen_roi({0, 0, 1, 1}, image, {-1, {1, 1}}), std::invalid_argument);
  EXPECT_THROW(widen_roi({0, 0, 1, 1}, image, {0, {0, 60}}), std::invalid_argument);
}

TEST(RoiFill, WidenedRegionsEqualTheFullFrameFillAndNothingElseIsWritten) {
  const cv::Mat1w d = holey(3);
  cv::Mat1w full;
  fill_holes_mode_into(d, full);
  ASSERT_GT(cv::countNonZero(d == 0), 0);
  const std::vector<cv::Rect> rois{{30, 40, 50, 20}, {200, 150, 30, 60}, {500, 0, 10, 10}};
  for (const RoiWidening widening : {RoiWidening{0, {80, 60}}, RoiWidening{4, {1, 1}}}) {
    const std::uint16_t sentinel = 7;
    cv::Mat1w out(d.size(), sentinel);
    fill_holes_mode_rois_into(d, rois, widening, out);
    cv::Mat1b written(d.size(), std::uint8_t(0));
    for (const cv::Rect& r : rois) {
      const cv::Rect wide = widen_roi(r, d.size(), widening);
      if (wide.empty()) continue;
      written(wide).setTo(255);
      EXPECT_EQ(cv::norm(out(wide), full(wide), cv::NORM_INF), 0.0) << wide;
    }
    EXPECT_EQ(cv::countNonZero((out != sentinel) & (written == 0)), 0);
    EXPECT_GT(cv::countNonZero(written), 0);
  }
}

}  // namespace
}  // namespace telex
