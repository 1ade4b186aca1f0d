// SPDX-License-Identifier: MIT
// Triple buffer and SPSC ring: the reader sees whole, newest values; nothing is torn or reordered.
#include <gtest/gtest.h>

#include <array>
#include <thread>

#include "telex/base/periodic.h"
#include "telex/base/spsc_ring.h"
#include "telex/base/triple_buffer.h"

namespace telex::local {
namespace {

struct Payload {
  std::array<std::uint64_t, 16> words{};
};

TEST(TripleBuffer, ReaderSeesNewestWholeValues) {
  TripleBuffer<Payload> tb;
  constexpr std::uint64_t kCount = 200000;
  std::thread writer([&] {
    for (std::uint64_t i = 1; i <= kCount; ++i) {
      auto& slot = tb.write_slot();
      slot.words.fill(i);
      tb.publish();
    }
  });
  std::uint64_t last = 0;
  std::uint64_t torn = 0, backwards = 0;
  while (last < kCount) {
    if (!tb.update()) continue;
    const auto& v = tb.read_slot();
    for (auto w : v.words) torn += (w != v.words[0]);
    backwards += (v.words[0] < last);
    last = v.words[0];
  }
  writer.join();
  EXPECT_EQ(torn, 0u);
  EXPECT_EQ(backwards, 0u);
  EXPECT_EQ(last, kCount);
  EXPECT_FALSE(tb.update());
}

TEST(SpscRing, DeliversInOrderAndCountsDropsWhenFull) {
  SpscRing<int> ring(4);
  for (int i = 0; i < 6; ++i) ring.push(i);
  EXPECT_EQ(ring.dropped(), 2u);
  int v = -1;
  for (int i = 0; i < 4; ++i) {
    ASSERT_TRUE(ring.pop(v));
    EXPECT_EQ(v, i);
  }
  EXPECT_FALSE(ring.pop(v));
}

TEST(SpscRing, TwoThreadsInOrder) {
  SpscRing<std::uint64_t> ring(64);
  constexpr std::uint64_t kCount = 100000;
  std::thread producer([&] {
    for (std::uint64_t i = 0; i < kCount; ++i)
      while (!ring.push(i)) std::this_thread::yield();
  });
  std::uint64_t expect = 0, v = 0;
  while (expect < kCount) {
    if (ring.pop(v)) {
      ASSERT_EQ(v, expect);
      ++expect;
    }
  }
  producer.join();
}

TEST(PeriodSummary, RateAndJitterFromPeriods) {
  std::vector<std::int64_t> p(1000, 1'000'000);
  p[10] = 1'500'000;  // one late tick
  p[11] = 500'000;    // and its catch-up
  const auto s = summarize_periods(p, 1'000'000);
  EXPECT_EQ(s.count, 1000u);
  EXPECT_NEAR(s.mean_rate_hz, 1000.0, 1e-6);
  EXPECT_DOUBLE_EQ(s.median_period_us, 1000.0);
  EXPECT_DOUBLE_EQ(s.max_jitter_us, 500.0);
  EXPECT_LT(s.p99_jitter_us, 500.0);
}

TEST(Percentile, Interpolates) {
  EXPECT_DOUBLE_EQ(percentile({1, 2, 3, 4, 5}, 0.5), 3.0);
  EXPECT_DOUBLE_EQ(percentile({1, 2, 3, 4}, 0.5), 2.5);
  EXPECT_DOUBLE_EQ(percentile({}, 0.5), 0.0);
}

}  // namespace
}  // namespace telex::local

namespace telex::local {
namespace {

TEST(Histogram, QuantilesToOneBinInFixedMemory) {
  Histogram h(1.0, 100);
  for (int i = 0; i < 1000; ++i) h.add(i % 50);  // uniform over 0..49
  h.add(1e9);                                    // lands in the overflow bin
  EXPECT_EQ(h.count(), 1001u);
  EXPECT_NEAR(h.quantile(0.5), 25.0, 1.0);
  EXPECT_NEAR(h.quantile(0.98), 49.5, 1.0);
  EXPECT_DOUBLE_EQ(h.quantile(1.0), 99.5);  // the overflow bin
  EXPECT_DOUBLE_EQ(h.max(), 1e9);
  EXPECT_DOUBLE_EQ(Histogram(1.0, 10).quantile(0.5), 0.0);
}

}  // namespace
}  // namespace telex::local
