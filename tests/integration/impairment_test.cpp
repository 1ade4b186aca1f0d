// SPDX-License-Identifier: MIT
// Tests for the impairment scheduler: rates over 100k datagrams, order, duplicates, corruption.
#include "telex/sim/impairment.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <numeric>

namespace telex::local {
namespace {

using namespace ::telex::sim;  // the simulators of the other end

constexpr int kN = 100'000;
constexpr std::int64_t kMs = 1'000'000;

// Datagram i carries i in its first 4 bytes so deliveries can be traced to their source.
std::vector<std::uint8_t> datagram(std::uint32_t i, std::size_t size = 64) {
  std::vector<std::uint8_t> d(size, 0xA5);
  for (int b = 0; b < 4; ++b) d[b] = static_cast<std::uint8_t>(i >> (8 * b));
  return d;
}
std::uint32_t id_of(const std::vector<std::uint8_t>& d) {
  return d[0] | d[1] << 8 | d[2] << 16 | static_cast<std::uint32_t>(d[3]) << 24;
}

struct Traced {
  std::int64_t at_ns;
  std::uint32_t id;
  std::size_t n;  // global delivery counter, breaks ties in arrival order like a FIFO timer queue
};

std::vector<Traced> run(Impairment& imp, int n, std::int64_t spacing_ns) {
  std::vector<Traced> out;
  for (int i = 0; i < n; ++i)
    for (auto& d : imp.process(datagram(static_cast<std::uint32_t>(i)), i * spacing_ns))
      out.push_back({d.deliver_at_ns, id_of(d.bytes), out.size()});
  std::stable_sort(out.begin(), out.end(),
                   [](const Traced& a, const Traced& b) { return a.at_ns < b.at_ns; });
  return out;
}

TEST(Impairment, PassThroughByDefault) {
  Impairment imp(ImpairmentConfig{});
  const auto d = datagram(9);
  const auto out = imp.process(d, 1234);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_EQ(out[0].deliver_at_ns, 1234);
  EXPECT_EQ(out[0].bytes, d);
}

TEST(Impairment, RatesWithinToleranceOver100k) {
  ImpairmentConfig c;
  c.loss = 0.05;
  c.reorder = 0.02;
  c.duplicate = 0.01;
  c.corrupt = 0.03;
  c.seed = 2026;
  Impairment imp(c);
  std::size_t corrupted_seen = 0;
  for (int i = 0; i < kN; ++i) {
    const auto d = datagram(static_cast<std::uint32_t>(i));
    const auto out = imp.process(d, i * kMs);
    if (!out.empty() && out[0].bytes != d) ++corrupted_seen;
  }
  const auto& k = imp.counters();
  EXPECT_EQ(k.received, static_cast<std::uint64_t>(kN));
  // Binomial sd at p = 0.05 over 1e5 is 0.0007; 0.003 is above 4 sd.
  EXPECT_NEAR(k.dropped / double(kN), 0.05, 0.003);
  const double kept = double(kN - k.dropped);
  EXPECT_NEAR(k.reordered / kept, 0.02, 0.002);
  EXPECT_NEAR(k.duplicated / kept, 0.01, 0.0015);
  EXPECT_NEAR(k.corrupted / kept, 0.03, 0.002);
  EXPECT_EQ(corrupted_seen, k.corrupted);  // every counted corruption changed the bytes
  EXPECT_EQ(k.delivered, k.received - k.dropped + k.duplicated);
}

TEST(Impairment, SameSeedSameOutcomeOtherSeedDiffers) {
  ImpairmentConfig c;
  c.loss = 0.2;
  c.jitter_ms = 5;
  c.delay_ms = 10;
  c.corrupt = 0.1;
  c.seed = 5;
  Impairment a(c), b(c);
  c.seed = 6;
  Impairment other(c);
  bool differs = false;
  for (int i = 0; i < 1000; ++i) {
    const auto d = datagram(static_cast<std::uint32_t>(i));
    const auto ra = a.process(d, i * kMs), rb = b.process(d, i * kMs);
    const auto ro = other.process(d, i * kMs);
    ASSERT_EQ(ra.size(), rb.size());
    for (std::size_t j = 0; j < ra.size(); ++j) {
      EXPECT_EQ(ra[j].deliver_at_ns, rb[j].deliver_at_ns);
      EXPECT_EQ(ra[j].bytes, rb[j].bytes);
    }
    if (ra.size() != ro.size() || (!ra.empty() && ra[0].deliver_at_ns != ro[0].deliver_at_ns))
      differs = true;
  }
  EXPECT_TRUE(differs);
}

TEST(Impairment, DelayAndJitterBoundsKeepOrderWithoutReorder) {
  ImpairmentConfig c;
  c.delay_ms = 50;
  c.jitter_ms = 20;
  c.seed = 3;
  Impairment imp(c);
  std::int64_t prev = 0;
  double sum_delay_ms = 0;
  for (int i = 0; i < kN; ++i) {
    const std::int64_t now = i * kMs / 4;  // 4 kHz: jitter alone would reorder a lot
    const auto out = imp.process(datagram(static_cast<std::uint32_t>(i)), now);
    ASSERT_EQ(out.size(), 1u);
    const std::int64_t delay = out[0].deliver_at_ns - now;
    EXPECT_GE(delay, 30 * kMs);
    // Order is kept by waiting behind an earlier, later-scheduled datagram: at most 70 ms.
    EXPECT_LE(delay, 70 * kMs);
    EXPECT_GE(out[0].deliver_at_ns, prev) << i;
    prev = out[0].deliver_at_ns;
    sum_delay_ms += double(delay) / kMs;
  }
  // Head-of-line waiting raises the mean above 50 ms; it stays below the 70 ms bound.
  EXPECT_GT(sum_delay_ms / kN, 50.0);
  EXPECT_LT(sum_delay_ms / kN, 70.0);
}

TEST(Impairment, ReorderedDatagramsAreOvertakenByLaterOnes) {
  ImpairmentConfig c;
  c.delay_ms = 5;
  c.reorder = 0.1;
  c.reorder_hold_ms = 10;
  c.seed = 11;
  Impairment imp(c);
  const auto out = run(imp, 20'000, kMs);  // 1 ms apart: a 10 ms hold is passed by ~10 others
  ASSERT_EQ(out.size(), 20'000u);
  // Count datagrams delivered after a higher id (each held one is passed by the next ones).
  std::uint32_t max_id = 0;
  std::size_t late = 0;
  for (const auto& t : out) {
    if (t.id < max_id) ++late;
    max_id = std::max(max_id, t.id);
  }
  EXPECT_NEAR(late / 20'000.0, 0.1, 0.01);
  EXPECT_EQ(late, imp.counters().reordered);
  // Every datagram delivered exactly once.
  std::vector<std::uint32_t> ids;
  for (const auto& t : out) ids.push_back(t.id);
  std::sort(ids.begin(), ids.end());
  for (std::uint32_t i = 0; i < ids.size(); ++i) ASSERT_EQ(ids[i], i);
}

TEST(Impairment, DuplicatesAreIdenticalAndAdjacent) {
  ImpairmentConfig c;
  c.duplicate = 0.5;
  c.delay_ms = 1;
  c.seed = 4;
  Impairment imp(c);
  std::size_t dups = 0;
  for (int i = 0; i < 1000; ++i) {
    const auto d = datagram(static_cast<std::uint32_t>(i), 100 + i % 50);
    const auto out = imp.process(d, i * kMs);
    ASSERT_GE(out.size(), 1u);
    ASSERT_LE(out.size(), 2u);
    for (const auto& o : out) {
      EXPECT_EQ(o.bytes, d);
      EXPECT_EQ(o.deliver_at_ns, out[0].deliver_at_ns);
    }
    dups += out.size() - 1;
  }
  EXPECT_EQ(dups, imp.counters().duplicated);
  EXPECT_NEAR(dups / 1000.0, 0.5, 0.06);
}

TEST(Impairment, CorruptionFlipsExactlyOneBitSpreadOverTheDatagram) {
  ImpairmentConfig c;
  c.corrupt = 1.0;
  c.seed = 8;
  Impairment imp(c);
  constexpr std::size_t kSize = 32;
  std::array<int, kSize * 8> hits{};
  for (int i = 0; i < 20'000; ++i) {
    const auto d = datagram(static_cast<std::uint32_t>(i), kSize);
    const auto out = imp.process(d, 0);
    ASSERT_EQ(out.size(), 1u);
    int flipped = 0;
    for (std::size_t b = 0; b < kSize; ++b) {
      const std::uint8_t x = d[b] ^ out[0].bytes[b];
      flipped += std::popcount(x);
      for (int bit = 0; bit < 8; ++bit)
        if (x >> bit & 1) ++hits[b * 8 + bit];
    }
    ASSERT_EQ(flipped, 1) << i;
  }
  // Every bit position gets hit (20000 / 256 = 78 expected each).
  EXPECT_GT(*std::min_element(hits.begin(), hits.end()), 40);
  EXPECT_LT(*std::max_element(hits.begin(), hits.end()), 130);
}

TEST(Impairment, LossOneDropsEverythingAndEmptyDatagramsSurvive) {
  ImpairmentConfig c;
  c.loss = 1.0;
  Impairment all(c);
  for (int i = 0; i < 100; ++i) EXPECT_TRUE(all.process(datagram(i), i).empty());
  EXPECT_EQ(all.counters().dropped, 100u);
  ImpairmentConfig k;
  k.corrupt = 1.0;
  Impairment empty(k);
  const auto out = empty.process({}, 5);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_TRUE(out[0].bytes.empty());
  EXPECT_EQ(empty.counters().corrupted, 0u);
}

TEST(Impairment, ValidateNamesTheField) {
  auto expect_bad = [](ImpairmentConfig c, const char* field) {
    try {
      Impairment imp(c);
      FAIL() << field << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
    }
  };
  ImpairmentConfig c;
  c.loss = 1.5;
  expect_bad(c, "loss");
  c = {};
  c.reorder = -0.1;
  expect_bad(c, "reorder");
  c = {};
  c.duplicate = std::nan("");
  expect_bad(c, "duplicate");
  c = {};
  c.corrupt = 2;
  expect_bad(c, "corrupt");
  c = {};
  c.delay_ms = -1;
  expect_bad(c, "delay_ms");
  c = {};
  c.jitter_ms = 1e9;
  expect_bad(c, "jitter_ms");
  c = {};
  c.rate_limit_mbit = -1;
  expect_bad(c, "rate_limit_mbit");
  c = {};
  c.rate_burst_bytes = 0;
  expect_bad(c, "rate_burst_bytes");
  c = {};
  c.rate_queue_ms = -5;
  expect_bad(c, "rate_queue_ms");
}

// A 19.2 Mbit/s stream into a 4 Mbit/s limit for 10 simulated seconds: what leaves is the rate
// (within the bucket and the queue), in order, never waiting longer than the queue allows; the
// rest is dropped and counted.
TEST(Impairment, RateLimitThrottlesToTheRateAndDropsWhatTheQueueCannotHold) {
  ImpairmentConfig c;
  c.rate_limit_mbit = 4.0;
  c.rate_burst_bytes = 15'000;
  c.rate_queue_ms = 50;
  Impairment imp(c);
  constexpr std::size_t kSize = 1'200;
  constexpr std::int64_t kSpacingNs = kMs / 2;  // 2400 datagrams/s = 19.2 Mbit/s
  constexpr int kCount = 20'000;                // 10 s
  std::uint64_t bytes_out = 0;
  std::int64_t prev_at_ns = 0;
  std::int64_t last_at_ns = 0;
  for (int i = 0; i < kCount; ++i) {
    const std::int64_t now = i * kSpacingNs;
    const auto out = imp.process(datagram(static_cast<std::uint32_t>(i), kSize), now);
    for (const auto& d : out) {
      EXPECT_GE(d.deliver_at_ns, prev_at_ns) << "order kept";
      EXPECT_LE(d.deliver_at_ns - now, 50 * kMs + 1) << "waited longer than the queue";
      prev_at_ns = last_at_ns = d.deliver_at_ns;
      bytes_out += d.bytes.size();
    }
  }
  const double rate_bytes_per_s = 4e6 / 8.0;
  // Out by the last delivery: at most the bucket plus the rate over that time; the queue was
  // full all along, so the link never idled: at least the rate over it less one datagram.
  const double span_s = double(last_at_ns) / 1e9;
  EXPECT_LE(double(bytes_out), c.rate_burst_bytes + rate_bytes_per_s * span_s + 1.0);
  EXPECT_GE(double(bytes_out), rate_bytes_per_s * span_s - double(kSize));
  const auto& k = imp.counters();
  EXPECT_EQ(k.bytes_out, bytes_out);
  EXPECT_GT(k.rate_dropped, k.received * 3 / 4) << "about 79 % of 19.2 Mbit/s cannot pass";
  EXPECT_EQ(k.delivered, k.received - k.rate_dropped);
  EXPECT_GT(k.rate_queued, 0u);
}

TEST(Impairment, RateLimitPassesAStreamBelowItUntouched) {
  ImpairmentConfig c;
  c.rate_limit_mbit = 10.0;
  c.delay_ms = 5;
  Impairment imp(c);
  for (int i = 0; i < 10'000; ++i) {  // 1200 bytes each ms: 9.6 Mbit/s, each alone
    const auto out = imp.process(datagram(static_cast<std::uint32_t>(i), 1'200), i * kMs);
    ASSERT_EQ(out.size(), 1u);
    EXPECT_EQ(out[0].deliver_at_ns, i * kMs + 5 * kMs) << i;
  }
  EXPECT_EQ(imp.counters().rate_dropped, 0u);
  EXPECT_EQ(imp.counters().rate_queued, 0u);
}

// The limit holds only in its window [from, until), counted from the first datagram: before and
// after it, a stream at twice the rate passes untouched; inside it, the stream queues and drops.
TEST(Impairment, RateLimitWindowStartsAndEnds) {
  ImpairmentConfig c;
  c.rate_limit_mbit = 1.0;
  c.rate_limit_from_s = 1.0;
  c.rate_limit_until_s = 2.0;
  Impairment imp(c);
  std::uint64_t queued_or_dropped[3] = {0, 0, 0};
  for (int i = 0; i < 3000; ++i) {  // 250 bytes each ms: 2 Mbit/s
    const auto before = imp.counters().rate_queued + imp.counters().rate_dropped;
    const auto out = imp.process(datagram(static_cast<std::uint32_t>(i), 250), 5 * kMs + i * kMs);
    queued_or_dropped[i / 1000] +=
        imp.counters().rate_queued + imp.counters().rate_dropped - before;
    if (i >= 2000) {  // after the window: on time again once the queue has drained
      ASSERT_EQ(out.size(), 1u);
    }
  }
  EXPECT_EQ(queued_or_dropped[0], 0u);
  EXPECT_GT(queued_or_dropped[1], 400u);
  EXPECT_EQ(queued_or_dropped[2], 0u);
  ImpairmentConfig bad = c;
  bad.rate_limit_until_s = 0.5;  // before from
  EXPECT_THROW(validate(bad), std::invalid_argument);
}

// The bucket lets a burst of its depth through at once; what is beyond waits in the queue, and
// what is beyond the queue is dropped.
TEST(Impairment, RateLimitBurstThenQueueThenDrop) {
  ImpairmentConfig c;
  c.rate_limit_mbit = 8.0;  // 1000 bytes per ms
  c.rate_burst_bytes = 3'000;
  c.rate_queue_ms = 2;  // 2000 bytes
  Impairment imp(c);
  std::vector<std::int64_t> at;
  for (int i = 0; i < 7; ++i) {
    const auto out = imp.process(datagram(static_cast<std::uint32_t>(i), 1'000), 0);
    at.push_back(out.empty() ? -1 : out[0].deliver_at_ns);
  }
  EXPECT_EQ(at, (std::vector<std::int64_t>{0, 0, 0, kMs, 2 * kMs, -1, -1}));
  EXPECT_EQ(imp.counters().rate_dropped, 2u);
  EXPECT_EQ(imp.counters().rate_queued, 2u);
}

}  // namespace
}  // namespace telex::local
