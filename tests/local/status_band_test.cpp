// SPDX-License-Identifier: MIT
// The views' status text fits every image it is drawn on: wrapped at spaces, nothing past the
// right margin, every word kept.
#include "telex/local/view/status_band.h"

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>
#include <sstream>

namespace telex::local {
namespace {

// A status line as the station writes it (long enough to overflow a 640 px view in one line).
const std::string kStatus =
    "haptic 999.7 Hz p99 186 us missed 4 | surface 30.0 fps latency 3.2 ms | tip 0: 1.25 N "
    "contact | tracking dropped 0 | upstream dropped 0 | head hold";

int width_of(const std::string& s, double scale, int thickness) {
  int base = 0;
  return cv::getTextSize(s, cv::FONT_HERSHEY_SIMPLEX, scale, thickness, &base).width;
}

TEST(StatusBand, WrapsAtSpacesKeepingEveryWordAndEachLineFits) {
  for (const int width : {200, 320, 640, 1280}) {
    const auto lines = wrap_status(kStatus, 0.45, 1, width);
    ASSERT_FALSE(lines.empty());
    std::string joined;
    for (const auto& l : lines) {
      EXPECT_LE(width_of(l, 0.45, 1), width) << width << ": " << l;
      joined += (joined.empty() ? "" : " ") + l;
    }
    EXPECT_EQ(joined, kStatus) << width;
  }
  EXPECT_EQ(wrap_status(kStatus, 0.45, 1, 4000).size(), 1u);
  EXPECT_GE(wrap_status(kStatus, 0.45, 1, 320).size(), 3u);
}

// Bright pixels in the columns at and right of x.
int bright_from(const cv::Mat3b& img, int x) {
  cv::Mat gray;
  cv::cvtColor(img.colRange(x, img.cols), gray, cv::COLOR_BGR2GRAY);
  return cv::countNonZero(gray > 128);
}

TEST(StatusBand, NothingIsDrawnPastTheRightMarginOfAnyImage) {
  for (const int width : {160, 320, 640}) {
    cv::Mat3b img(width * 3 / 4, width, cv::Vec3b(60, 60, 60));
    draw_status_band(img, kStatus, 0.45 * std::max(1, width / 320), std::max(1, width / 320));
    EXPECT_EQ(bright_from(img, width - 4), 0) << width << " px: text cut off at the right edge";
    EXPECT_GT(bright_from(img, 0), 50) << width << " px: no text drawn";
  }
  // A single word wider than the image shrinks to fit.
  cv::Mat3b narrow(60, 80, cv::Vec3b(60, 60, 60));
  draw_status_band(narrow, "supercalifragilistic", 0.45, 1);
  EXPECT_EQ(bright_from(narrow, 76), 0);
  EXPECT_GT(bright_from(narrow, 0), 5);
}

}  // namespace
}  // namespace telex::local
