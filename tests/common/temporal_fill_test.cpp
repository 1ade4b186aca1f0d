// SPDX-License-Identifier: MIT
// Temporal fill: history ageing by frames and by time, reset on size change, no self-refresh.
#include "telex/common/temporal_fill.h"

#include <gtest/gtest.h>

namespace telex {
namespace {

TEST(TemporalFill, FillsFromThePreviousFrameWhileYoung) {
  TemporalFillOptions o;
  o.max_age_frames = 2;
  TemporalFill tf(o);
  cv::Mat1w a(4, 4, std::uint16_t{800}), out;
  auto r = tf.apply(a, 0.0, out);
  EXPECT_EQ(r.holes_in, 0u);
  cv::Mat1w b = a.clone();
  b(1, 1) = 0;
  b(2, 2) = 0;
  b(2, 3) = 950;
  r = tf.apply(b, 33.0, out);
  EXPECT_EQ(r.holes_in, 2u);
  EXPECT_EQ(r.filled, 2u);
  EXPECT_EQ(r.holes_out, 0u);
  EXPECT_EQ(out(1, 1), 800);
  EXPECT_EQ(out(2, 3), 950);  // measured pixels pass through
  // Age 2 is still allowed, age 3 is not: the filled pixels never refresh their own history.
  r = tf.apply(b, 66.0, out);
  EXPECT_EQ(r.filled, 2u);
  r = tf.apply(b, 99.0, out);
  EXPECT_EQ(r.filled, 0u);
  EXPECT_EQ(out(1, 1), 0);
}

// Issue 16: the history holds measurements only. A pixel the spatial fill guessed in one frame is
// used in that frame and forgotten: when it is a hole again, the older measurement (or nothing)
// fills it, never the guess.
TEST(TemporalFill, ASpatialGuessIsUsedButNeverRemembered) {
  TemporalFill tf;
  cv::Mat1w measured(2, 2, std::uint16_t{0}), filled, out;
  measured(0, 0) = 700;  // measured once, frame 1
  filled = measured.clone();
  auto r = tf.apply(measured, filled, 0.0, out);
  EXPECT_EQ(out(0, 0), 700);
  EXPECT_EQ(r.filled, 0u);
  // Frame 2: (0,0) and (1,1) are holes; the spatial fill guessed 999 for both.
  measured.setTo(0);
  filled.setTo(0);
  filled(0, 0) = 999;
  filled(1, 1) = 999;
  r = tf.apply(measured, filled, 33.0, out);
  EXPECT_EQ(out(0, 0), 999) << "this frame uses the guess";
  EXPECT_EQ(out(1, 1), 999);
  EXPECT_EQ(r.holes_in, 2u);
  // Frame 3: no guess. (0,0) comes back from its measurement two frames ago, (1,1) stays a hole.
  filled.setTo(0);
  r = tf.apply(measured, filled, 66.0, out);
  EXPECT_EQ(out(0, 0), 700) << "the history kept the measurement, not the guess";
  EXPECT_EQ(out(1, 1), 0) << "a guess is never remembered";
  EXPECT_EQ(r.filled, 1u);
}

TEST(TemporalFill, NeverSeenPixelsStayHoles) {
  TemporalFill tf;
  cv::Mat1w a(3, 3, std::uint16_t{0}), out;
  a(0, 0) = 500;
  const auto r = tf.apply(a, 0.0, out);
  EXPECT_EQ(r.holes_in, 8u);
  EXPECT_EQ(r.filled, 0u);
}

TEST(TemporalFill, MaxAgeInMilliseconds) {
  TemporalFillOptions o;
  o.max_age_frames = 100;
  o.max_age_ms = 50.0;
  TemporalFill tf(o);
  cv::Mat1w a(2, 2, std::uint16_t{700}), hole(2, 2, std::uint16_t{0}), out;
  tf.apply(a, 1000.0, out);
  EXPECT_EQ(tf.apply(hole, 1040.0, out).filled, 4u);
  EXPECT_EQ(out(0, 0), 700);
  EXPECT_EQ(tf.apply(hole, 1050.0, out).filled, 4u);
  EXPECT_EQ(tf.apply(hole, 1050.5, out).filled, 0u);
}

TEST(TemporalFill, SizeChangeOrClockGoingBackResetsHistory) {
  TemporalFill tf;
  cv::Mat1w a(2, 2, std::uint16_t{700}), out;
  tf.apply(a, 0.0, out);
  cv::Mat1w big(3, 3, std::uint16_t{0});
  auto r = tf.apply(big, 10.0, out);
  EXPECT_TRUE(r.history_reset);
  EXPECT_EQ(r.filled, 0u);
  EXPECT_EQ(out.size(), big.size());
  cv::Mat1w c(3, 3, std::uint16_t{600}), hole(3, 3, std::uint16_t{0});
  tf.apply(c, 20.0, out);
  r = tf.apply(hole, 5.0, out);
  EXPECT_TRUE(r.history_reset);
  EXPECT_EQ(r.filled, 0u);
}

TEST(TemporalFill, RejectsBadOptions) {
  TemporalFillOptions o;
  o.max_age_frames = 0;
  EXPECT_THROW(TemporalFill{o}, std::invalid_argument);
  o = {};
  o.max_age_ms = -1.0;
  EXPECT_THROW(TemporalFill{o}, std::invalid_argument);
}

}  // namespace
}  // namespace telex
