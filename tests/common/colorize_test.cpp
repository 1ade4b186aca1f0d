// SPDX-License-Identifier: MIT
// Tests of the depth and normal false-colour views.
#include "telex/common/colorize.h"

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

namespace telex {
namespace {

cv::Vec3b turbo(int level) {
  cv::Mat1b one(1, 1, static_cast<uchar>(level));
  cv::Mat3b c;
  cv::applyColorMap(one, c, cv::COLORMAP_TURBO);
  return c(0, 0);
}

TEST(Colorize, HolesBlackNearRedFarBlue) {
  cv::Mat1w d(1, 4);
  d << 0, 500, 1000, 3000;
  const cv::Mat3b c = colorize_depth(d, 500, 3000);
  EXPECT_EQ(c(0, 0), cv::Vec3b(0, 0, 0));
  EXPECT_EQ(c(0, 1), turbo(255));     // nearest: the red end
  EXPECT_EQ(c(0, 3), turbo(0));       // farthest: the blue end
  EXPECT_EQ(c(0, 2), turbo(204));     // (3000 - 1000) / 2500 of the way
  EXPECT_GT(c(0, 1)[2], c(0, 1)[0]);  // red over blue (BGR)
  EXPECT_GT(c(0, 3)[0], c(0, 3)[2]);
  EXPECT_THROW(colorize_depth(d, 3000, 500), std::invalid_argument);
}

TEST(Colorize, AutoRangeUsesValidPercentiles) {
  cv::Mat1w d(10, 100);
  for (int v = 0; v < 10; ++v)
    for (int u = 0; u < 100; ++u) d(v, u) = static_cast<std::uint16_t>(1000 + 10 * u);
  d(0, 0) = 0;      // holes do not count
  d(5, 5) = 60000;  // an outlier beyond the 99th percentile
  const cv::Mat3b c = colorize_depth(d);
  EXPECT_EQ(c(0, 0), cv::Vec3b(0, 0, 0));
  EXPECT_EQ(c(5, 5), turbo(0));    // clamped to the far end
  EXPECT_EQ(c(9, 1), turbo(255));  // the 1st percentile (1010 mm) is the near end
}

TEST(Colorize, NormalsMapToRgb) {
  cv::Mat3f n(1, 3);
  n(0, 0) = cv::Vec3f(0, 0, 0);
  n(0, 1) = cv::Vec3f(0, 0, -1);
  n(0, 2) = cv::Vec3f(1, 0, 0);
  const cv::Mat3b c = colorize_normals(n);
  EXPECT_EQ(c(0, 0), cv::Vec3b(0, 0, 0));
  EXPECT_EQ(c(0, 1), cv::Vec3b(0, 128, 128));
  EXPECT_EQ(c(0, 2), cv::Vec3b(128, 128, 255));
}

}  // namespace
}  // namespace telex
