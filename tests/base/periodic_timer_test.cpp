// SPDX-License-Identifier: MIT
// PeriodicTimer against a simulated clock: deadlines without drift, overruns counted and skipped.
#include <gtest/gtest.h>

#include <vector>

#include "telex/base/periodic.h"

namespace telex {
namespace {

// Time moves only when the timer sleeps (to the deadline, plus a wake-up latency) or when the
// test says work took time.
class SimClock final : public TimerClock {
 public:
  std::int64_t now_ns() override { return now; }
  void sleep_until_ns(std::int64_t deadline_ns) override {
    deadlines.push_back(deadline_ns);
    if (deadline_ns > now) now = deadline_ns;
    now += wake_latency_ns;
  }
  std::int64_t now = 5'000'000'000;
  std::int64_t wake_latency_ns = 0;
  std::vector<std::int64_t> deadlines;
};

TEST(PeriodicTimer, DeadlinesAreAbsoluteSoLatencyAndWorkDoNotAccumulate) {
  SimClock clock;
  clock.wake_latency_ns = 40'000;  // 40 us late on every wake-up
  PeriodicTimer timer(1'000'000, clock);
  const std::int64_t start = clock.now;
  for (int i = 0; i < 1000; ++i) {
    const std::int64_t woke = timer.wait_next();
    EXPECT_EQ(woke, start + (i + 1) * 1'000'000 + 40'000);
    clock.now += 300'000;  // the tick's work
  }
  ASSERT_EQ(clock.deadlines.size(), 1000u);
  for (std::size_t i = 0; i < clock.deadlines.size(); ++i)
    EXPECT_EQ(clock.deadlines[i], start + static_cast<std::int64_t>(i + 1) * 1'000'000) << i;
  EXPECT_EQ(timer.missed(), 0u);
}

TEST(PeriodicTimer, AnOverrunIsCountedAndSkippedNotBurst) {
  SimClock clock;
  PeriodicTimer timer(1'000'000, clock);
  const std::int64_t start = clock.now;
  timer.wait_next();       // deadline start + 1 ms
  clock.now += 3'500'000;  // a tick that took 3.5 periods
  const std::int64_t woke = timer.wait_next();
  // The next deadline (start + 2 ms) lies 2.5 periods in the past: the deadlines at 2 and 3 ms are
  // missed, the one at 4 ms ticks at once (half a period late) and the grid is kept.
  EXPECT_EQ(timer.missed(), 2u);
  EXPECT_EQ(woke, start + 1'000'000 + 3'500'000);
  EXPECT_EQ(timer.deadline_ns(), start + 4'000'000);
  timer.wait_next();
  EXPECT_EQ(clock.deadlines.back(), start + 5'000'000);
  EXPECT_EQ(timer.missed(), 2u);
}

TEST(PeriodicTimer, ALateTickWithinOnePeriodCatchesUpWithoutMissing) {
  SimClock clock;
  PeriodicTimer timer(1'000'000, clock);
  const std::int64_t start = clock.now;
  timer.wait_next();
  clock.now += 1'600'000;  // 0.6 periods past the next deadline
  const std::int64_t woke = timer.wait_next();
  EXPECT_EQ(woke, start + 2'600'000);  // the deadline has passed: no sleep
  EXPECT_EQ(timer.missed(), 0u);
  timer.wait_next();
  EXPECT_EQ(clock.deadlines.back(), start + 3'000'000);  // back on the original grid
}

TEST(PeriodicTimerDeathTest, ANonPositivePeriodIsACallerBug) {
  SimClock clock;
  EXPECT_DEATH(PeriodicTimer(0, clock), "periodic.cpp:[0-9]+: TELEX_DEMAND\\(period_ns > 0\\)");
}

// The accounting the station's summary and the loopback tests rely on: over any mix of on-time
// ticks, late wake-ups and overruns of many periods, every deadline from the first to the last is
// either ticked or missed, exactly.
TEST(PeriodicTimer, EveryDeadlineIsTickedOrMissedWhateverTheOverruns) {
  SimClock clock;
  const std::int64_t period = 1'000'000;
  PeriodicTimer timer(period, clock);
  std::uint64_t ticks = 0;
  std::int64_t first = 0;
  std::uint32_t lcg = 12345;
  for (int i = 0; i < 5000; ++i) {
    timer.wait_next();
    if (ticks++ == 0) first = timer.deadline_ns();
    lcg = lcg * 1664525u + 1013904223u;
    const std::uint32_t r = lcg >> 8;
    // Mostly short work; sometimes a late wake-up within a period, sometimes a stall of up to 7.9.
    clock.wake_latency_ns = (r % 7 == 0) ? static_cast<std::int64_t>(r % 900'000) : 0;
    clock.now += (r % 13 == 0) ? static_cast<std::int64_t>(r % 7'900'000) : 200'000;
  }
  const std::int64_t deadlines = (timer.deadline_ns() - first) / period + 1;
  EXPECT_GT(timer.missed(), 100u);
  EXPECT_EQ(static_cast<std::int64_t>(ticks + timer.missed()), deadlines);
  for (std::size_t i = 1; i < clock.deadlines.size(); ++i)
    EXPECT_EQ((clock.deadlines[i] - clock.deadlines[0]) % period, 0) << i;
}

}  // namespace
}  // namespace telex
