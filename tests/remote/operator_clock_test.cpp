// SPDX-License-Identifier: MIT
// OperatorClock: the station's clock offset from the remote's heartbeat probes, the least-delayed
// answer of the newest eight, and stamps that are no answer refused.
#include "telex/remote/operator_clock.h"

#include <gtest/gtest.h>

namespace telex::remote {
namespace {

constexpr std::int64_t kMs = 1'000'000;

// A probe sent at `t1` (remote) to a station whose clock is `offset` ahead, `out` on the way
// there, `back` on the way back, answered at once.
void answer(OperatorClock& c, std::int64_t t1, std::int64_t offset, std::int64_t out,
            std::int64_t back) {
  const std::int64_t t2 = t1 + out + offset;
  ASSERT_TRUE(c.add(t1, t2, t2, t1 + out + back));
}

TEST(OperatorClock, NothingBeforeTheFirstAnswer) {
  const OperatorClock c;
  EXPECT_FALSE(c.offset_ns());
  EXPECT_FALSE(c.station_time(5));
  EXPECT_EQ(c.delay_ns(), -1);
}

TEST(OperatorClock, ASymmetricRoundTripGivesTheOffsetExactly) {
  OperatorClock c;
  answer(c, 1000 * kMs, 250 * kMs, kMs, kMs);
  EXPECT_EQ(c.offset_ns(), 250 * kMs);
  EXPECT_EQ(c.delay_ns(), 2 * kMs);
  EXPECT_EQ(c.station_time(2000 * kMs), 2250 * kMs);
}

// An answer that waited 300 ms in the station's send queue is off by half the asymmetry (149.5
// ms); the quickest of the newest eight is used, and a quick one stops counting once eight newer
// ones came.
TEST(OperatorClock, TheLeastDelayedAnswerOfTheNewestEightWins) {
  OperatorClock c;
  const std::int64_t offset = -40 * kMs;
  answer(c, 0, offset, kMs, 300 * kMs);
  EXPECT_EQ(c.offset_ns(), offset + (kMs - 300 * kMs) / 2);
  answer(c, 250 * kMs, offset, kMs, kMs);
  EXPECT_EQ(c.offset_ns(), offset);
  // Seven slower answers (out 1 ms, back 7 ms: off by -3 ms) from a clock that moved on 3 ms: the
  // 2 ms answer is still among the newest eight.
  for (int i = 2; i < 9; ++i) answer(c, i * 250 * kMs, offset + 3 * kMs, kMs, 7 * kMs);
  EXPECT_EQ(c.offset_ns(), offset);
  EXPECT_EQ(c.delay_ns(), 2 * kMs);
  // The ninth pushes it out: the slower ones' offset, biased by their asymmetry.
  answer(c, 9 * 250 * kMs, offset + 3 * kMs, kMs, 7 * kMs);
  EXPECT_EQ(c.offset_ns(), offset + 3 * kMs - 3 * kMs);
  EXPECT_EQ(c.delay_ns(), 8 * kMs);
}

TEST(OperatorClock, StampsThatAreNoAnswerAreRefused) {
  OperatorClock c;
  EXPECT_FALSE(c.add(100, 500, 600, 90));   // answered before it was sent
  EXPECT_FALSE(c.add(100, 600, 500, 200));  // the station sent before it received
  EXPECT_FALSE(c.add(100, 0, 1000, 200));   // the station's span longer than the round trip
  EXPECT_FALSE(c.offset_ns());
  EXPECT_TRUE(c.add(100, 5000, 5000, 200));
  EXPECT_EQ(c.offset_ns(), ((5000 - 100) + (5000 - 200)) / 2);
}

}  // namespace
}  // namespace telex::remote
