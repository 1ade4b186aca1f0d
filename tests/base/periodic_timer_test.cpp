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
  // The next deadline (start + 2 ms) lies 2.5 periods in the past: two whole periods are missed
  // and the timer realigns one period after now instead of firing the late ticks at once.
  EXPECT_EQ(timer.missed(), 2u);
  EXPECT_EQ(woke, start + 1'000'000 + 3'500'000 + 1'000'000);
  timer.wait_next();
  EXPECT_EQ(clock.deadlines.back(), woke + 1'000'000);
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

}  // namespace
}  // namespace telex
