// SPDX-License-Identifier: MIT
// RepairPolicy: a lost tile is asked again after max(minimum, transit + 2 RTT).
#include "telex/local/link/repair_policy.h"

#include <gtest/gtest.h>

namespace telex::local {
namespace {

constexpr std::int64_t kMs = 1'000'000;

TEST(RepairPolicy, TheMinimumHoldsUntilTransitAndRoundTripExceedIt) {
  RepairPolicy p(0.025, 0.25);
  EXPECT_EQ(p.retry_ns(0), 25 * kMs);
  EXPECT_EQ(p.retry_ns(5 * kMs), 25 * kMs);  // 2 x 5 ms < 25 ms
  EXPECT_EQ(p.retry_ns(20 * kMs), 40 * kMs);
  EXPECT_EQ(p.key_interval_ns(), 250 * kMs);
}

TEST(RepairPolicy, RetryIsTransitPlusTwoRoundTrips) {
  RepairPolicy p(0.001, 0.25);
  // Captured at 1000 ms on the sender, whose clock is 100 ms ahead; closed at 930 ms here.
  p.on_frame(930 * kMs, 1000 * kMs, 100 * kMs);
  EXPECT_EQ(p.transit_ns(), 30 * kMs);
  EXPECT_EQ(p.retry_ns(10 * kMs), 50 * kMs);
}

TEST(RepairPolicy, TransitIsSmoothedOverAboutEightFrames) {
  RepairPolicy p(0.0, 0.25);
  p.on_frame(40 * kMs, 0, 0);  // the first frame is taken as it is
  EXPECT_EQ(p.transit_ns(), 40 * kMs);
  p.on_frame(1000 * kMs + 120 * kMs, 1000 * kMs, 0);  // one slow frame moves it an eighth
  EXPECT_EQ(p.transit_ns(), 50 * kMs);
}

TEST(RepairPolicy, ANegativeTransitNeverShortensTheRetry) {
  // Clocks not yet synchronised: the capture looks later than its arrival.
  RepairPolicy p(0.0, 0.25);
  p.on_frame(0, 80 * kMs, 0);
  EXPECT_LT(p.transit_ns(), 0);
  EXPECT_EQ(p.retry_ns(10 * kMs), 20 * kMs);
}

}  // namespace
}  // namespace telex::local
