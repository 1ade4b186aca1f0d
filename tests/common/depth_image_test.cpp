// SPDX-License-Identifier: MIT
// Tests for the depth image type and intrinsics scaling.
#include "telex/common/depth_image.h"

#include <gtest/gtest.h>

namespace telex {
namespace {

TEST(Intrinsics, ScalingHalvesFocalAndKeepsPixelCentres) {
  const Intrinsics k = kinect_v1_intrinsics();
  const Intrinsics h = k.scaled(320, 240);
  EXPECT_DOUBLE_EQ(h.fx, 262.5);
  EXPECT_DOUBLE_EQ(h.fy, 262.5);
  EXPECT_DOUBLE_EQ(h.cx, 159.5);  // centre of a 320-wide image
  EXPECT_DOUBLE_EQ(h.cy, 119.5);
  EXPECT_EQ(h.width, 320);
  EXPECT_EQ(kinect_v1_intrinsics(320, 240), h);
}

TEST(DepthImage, CountsHoles) {
  cv::Mat1w d(4, 5, std::uint16_t{1000});
  d(0, 0) = 0;
  d(3, 4) = 0;
  EXPECT_EQ(count_holes(d), 2u);
}

}  // namespace
}  // namespace telex
