// SPDX-License-Identifier: MIT
// The depth stabiliser: its pure kernel and the per-stream state the remote pipeline keeps.
#include "telex/common/stabilise.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <stdexcept>

namespace telex {
namespace {

TEST(Stabiliser, ZeroToleranceIsBitExact) {
  Stabiliser s(0.0);
  std::mt19937 rng(3);
  cv::Mat1w in(48, 64), out;
  for (int i = 0; i < 5; ++i) {
    cv::randu(in, 0, 4000);
    s.apply(in, out);
    EXPECT_EQ(cv::norm(in, out, cv::NORM_INF), 0.0);
  }
}

TEST(Stabiliser, HoldsWithinTheNoiseBandAndFollowsRealChanges) {
  Stabiliser s(3.0, /*confirm_frames=*/1);
  // At 1 m the Nguyen sigma is 1.2 + 1.9 * 0.36 = 1.88 mm, so k = 3 gives a 5 mm band.
  EXPECT_EQ(s.tolerance_mm(1000), 5);
  cv::Mat1w a(2, 2, std::uint16_t(1000)), out;
  s.apply(a, out);
  cv::Mat1w b = (cv::Mat1w(2, 2) << 1004, 996, 1006, 0);
  s.apply(b, out);
  EXPECT_EQ(out(0, 0), 1000);  // within 5 mm: held
  EXPECT_EQ(out(0, 1), 1000);
  EXPECT_EQ(out(1, 0), 1006);  // beyond: follows
  EXPECT_EQ(out(1, 1), 0);     // holes pass through
  cv::Mat1w c = (cv::Mat1w(2, 2) << 1000, 1000, 1003, 1000);
  s.apply(c, out);
  EXPECT_EQ(out(1, 0), 1006);  // held around the new value
  EXPECT_EQ(out(1, 1), 1000);  // after a hole the pixel restarts from the measurement
}

TEST(Stabiliser, SmallExcursionsMustPersistLargeJumpsPassAtOnce) {
  Stabiliser s(3.0, /*confirm_frames=*/2,
               /*immediate_factor=*/3.0);  // band 5 mm, jump 15 mm at 1 m
  cv::Mat1w out;
  s.apply(cv::Mat1w(1, 3, std::uint16_t(1000)), out);
  s.apply((cv::Mat1w(1, 3) << 1008, 1008, 1100), out);
  EXPECT_EQ(out(0, 0), 1000);  // one frame outside the band: noise until proven otherwise
  EXPECT_EQ(out(0, 1), 1000);
  EXPECT_EQ(out(0, 2), 1100);  // 100 mm: real motion, no delay
  s.apply((cv::Mat1w(1, 3) << 1001, 1009, 1100), out);
  EXPECT_EQ(out(0, 0), 1000);  // back inside: the excursion is forgotten
  EXPECT_EQ(out(0, 1), 1009);  // second frame outside: taken
  s.apply((cv::Mat1w(1, 3) << 1007, 1009, 1100), out);
  EXPECT_EQ(out(0, 0), 1000);  // a new excursion starts counting from one again
  EXPECT_THROW(Stabiliser(-1.0), std::invalid_argument);
  EXPECT_THROW(Stabiliser(1.0, 0), std::invalid_argument);
}

TEST(Stabiliser, TileByTileEqualsWholeFrame) {
  Stabiliser whole(3.0, 2), tiled(3.0, 2);
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0.0, 4.0);
  cv::Mat1w base(60, 80);
  cv::randu(base, 800, 3000);
  cv::Mat1w out_whole, out_tiled(base.size());
  for (int f = 0; f < 6; ++f) {
    cv::Mat1w in = base.clone();
    for (auto& v : in) v = static_cast<std::uint16_t>(std::max(0.0, v + noise(rng) * (f % 3)));
    in(cv::Rect(5 * f, 7, 9, 5)).setTo(0);
    whole.apply(in, out_whole);
    tiled.begin(in.size());
    for (int y = 0; y < 60; y += 20)
      for (int x = 0; x < 80; x += 16) tiled.apply_rect(in, cv::Rect(x, y, 16, 20), out_tiled);
    EXPECT_EQ(cv::norm(out_whole, out_tiled, cv::NORM_INF), 0.0) << f;
  }
  cv::Mat1w wrong;
  EXPECT_DEATH(tiled.apply_rect(base, cv::Rect(0, 0, 4, 4), wrong), "TELEX_DEMAND");
}

TEST(StabiliseKernel, StateLivesInTheCallersImagesAndOnlyRectIsTouched) {
  const StabiliseThresholds t(3.0, 3.0);  // band 5 mm, jump 15 mm at 1 m
  cv::Mat1w held(2, 4, std::uint16_t(1000)), out(2, 4, std::uint16_t(7));
  cv::Mat1b outside(2, 4, std::uint8_t(0));
  const cv::Mat1w in = (cv::Mat1w(2, 4) << 1004, 1008, 1100, 0, 1004, 1008, 1100, 0);
  stabilise_rect(in, cv::Rect(0, 0, 4, 1), t, 2, held, outside, out);
  EXPECT_EQ(out(0, 0), 1000);  // inside the band: held
  EXPECT_EQ(out(0, 1), 1000);  // outside, first frame: held, counted
  EXPECT_EQ(outside(0, 1), 1);
  EXPECT_EQ(out(0, 2), 1100);  // beyond the jump: taken at once
  EXPECT_EQ(out(0, 3), 0);     // a hole passes through and resets the pixel
  EXPECT_EQ(held(0, 3), 0);
  EXPECT_EQ(out(1, 0), 7);  // the second row is outside the rect: untouched
  EXPECT_EQ(held(1, 2), 1000);
  stabilise_rect(in, cv::Rect(0, 0, 4, 1), t, 2, held, outside, out);
  EXPECT_EQ(out(0, 1), 1008);  // second frame outside the band: taken
  EXPECT_EQ(outside(0, 1), 0);
  EXPECT_THROW(StabiliseThresholds(1.0, 0.5), std::invalid_argument);
}

}  // namespace
}  // namespace telex
