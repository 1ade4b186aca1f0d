// SPDX-License-Identifier: MIT
// VideoReorder: pairs leave in encode_seq order; a gap is NACKed at once, again after the retry
// interval, and given up at its deadline; what comes late is dropped and counted.
#include "telex/local/video_reorder.h"

#include <gtest/gtest.h>

namespace telex::local {
namespace {

using Bytes = std::vector<std::uint8_t>;
constexpr std::int64_t kMs = 1'000'000;

Bytes pair_bytes(std::uint32_t seq) { return Bytes{static_cast<std::uint8_t>(seq)}; }

struct Stream {
  VideoReorder reorder;
  std::vector<std::uint32_t> out;  // seqs released, in order
  std::vector<proto::VideoNack> nacks;
  explicit Stream(VideoReorderConfig c = {}) : reorder(c) {}
  void push(std::uint32_t seq, std::int64_t now_ns) { reorder.push(seq, pair_bytes(seq), now_ns); }
  void poll(std::int64_t now_ns, std::int64_t rtt_ns = kMs) {
    std::vector<Bytes> ready;
    reorder.poll(now_ns, rtt_ns, ready, nacks);
    for (const Bytes& b : ready) out.push_back(b[0]);
  }
};

TEST(VideoReorder, InOrderPairsPassStraightThrough) {
  Stream r;
  for (std::uint32_t s = 10; s < 15; ++s) {
    r.push(s, s * 33 * kMs);
    r.poll(s * 33 * kMs);
  }
  EXPECT_EQ(r.out, (std::vector<std::uint32_t>{10, 11, 12, 13, 14}));
  EXPECT_TRUE(r.nacks.empty());
  EXPECT_EQ(r.reorder.counters().in_order, 5u);
  EXPECT_EQ(r.reorder.next_wake_ns(kMs), 0);
}

TEST(VideoReorder, AGapHoldsWhatFollowsAsksOnceAndReleasesAllWhenRepaired) {
  Stream r;
  r.push(1, 0);
  r.poll(0);
  r.push(3, 33 * kMs);  // 2 lost
  r.push(4, 34 * kMs);
  r.poll(34 * kMs);
  EXPECT_EQ(r.out, (std::vector<std::uint32_t>{1}));
  ASSERT_EQ(r.nacks.size(), 1u);
  EXPECT_EQ(r.nacks[0], (proto::VideoNack{2, 1}));
  r.poll(36 * kMs);  // before the retry interval: nothing new
  EXPECT_EQ(r.nacks.size(), 1u);
  r.push(2, 37 * kMs);  // the resend
  r.poll(37 * kMs);
  EXPECT_EQ(r.out, (std::vector<std::uint32_t>{1, 2, 3, 4}));
  EXPECT_EQ(r.reorder.counters().repaired, 1u);
  EXPECT_EQ(r.reorder.counters().held, 2u);
  EXPECT_EQ(r.reorder.counters().given_up, 0u);
  r.push(2, 40 * kMs);  // a second copy
  r.poll(40 * kMs);
  EXPECT_EQ(r.reorder.counters().late, 1u);
  EXPECT_EQ(r.out.size(), 4u);
}

TEST(VideoReorder, ConsecutiveLossesAreOneNackAndRetriesStopAtTheLimit) {
  VideoReorderConfig c;
  c.hold_min_ns = c.hold_max_ns = 1000 * kMs;  // long enough to see every retry
  c.max_nacks = 3;
  Stream r(c);
  r.push(5, 0);
  r.poll(0);
  r.push(9, 10 * kMs);  // 6, 7, 8 lost
  r.poll(10 * kMs, 2 * kMs);
  ASSERT_EQ(r.nacks.size(), 1u);
  EXPECT_EQ(r.nacks[0], (proto::VideoNack{6, 3}));
  // The retry interval is max(8 ms, 2 RTT + 2 ms): 8 ms at a 2 ms round trip.
  EXPECT_EQ(r.reorder.next_wake_ns(2 * kMs), 18 * kMs);
  r.poll(17 * kMs, 2 * kMs);
  EXPECT_EQ(r.nacks.size(), 1u);
  r.poll(18 * kMs, 2 * kMs);
  r.poll(26 * kMs, 2 * kMs);
  r.poll(34 * kMs, 2 * kMs);  // the limit: three asks
  r.poll(60 * kMs, 2 * kMs);
  EXPECT_EQ(r.nacks.size(), 3u);
  EXPECT_EQ(r.reorder.counters().nacks, 3u);
  EXPECT_EQ(r.out, (std::vector<std::uint32_t>{5}));
}

TEST(VideoReorder, AGapPastItsDeadlineIsGivenUpAndLateCopiesAreDropped) {
  Stream r;  // 1 ms round trip: the deadline is max(20 ms, 3 RTT + 10 ms) = 20 ms after the gap
  r.push(1, 0);
  r.push(3, 33 * kMs);
  r.poll(33 * kMs);
  EXPECT_EQ(r.reorder.next_wake_ns(kMs), 33 * kMs + 8 * kMs);  // the retry comes first
  r.poll(52 * kMs);
  EXPECT_EQ(r.out, (std::vector<std::uint32_t>{1}));
  r.poll(53 * kMs);
  EXPECT_EQ(r.out, (std::vector<std::uint32_t>{1, 3}));
  EXPECT_EQ(r.reorder.counters().given_up, 1u);
  r.push(2, 60 * kMs);
  r.poll(60 * kMs);
  EXPECT_EQ(r.reorder.counters().late, 1u);
  EXPECT_EQ(r.out.size(), 2u);
  EXPECT_EQ(r.reorder.next_wake_ns(kMs), 0);
}

TEST(VideoReorder, TheDeadlineFollowsTheRoundTripUpToItsCap) {
  Stream r;
  r.push(1, 0);
  r.push(3, 0);
  r.poll(0, 100 * kMs);  // a 100 ms round trip: 3 RTT + 10 ms is beyond the 60 ms cap
  r.poll(59 * kMs, 100 * kMs);
  EXPECT_EQ(r.out, (std::vector<std::uint32_t>{1}));
  r.poll(60 * kMs, 100 * kMs);
  EXPECT_EQ(r.out, (std::vector<std::uint32_t>{1, 3}));
}

TEST(VideoReorder, TooManyHeldPairsGiveTheGapUpEarly) {
  VideoReorderConfig c;
  c.max_held = 3;
  Stream r(c);
  r.push(0, 0);
  for (std::uint32_t s = 2; s <= 4; ++s) r.push(s, 0);
  r.poll(0);
  EXPECT_EQ(r.out, (std::vector<std::uint32_t>{0}));
  r.push(5, 0);  // the fourth pair held
  r.poll(0);
  EXPECT_EQ(r.out, (std::vector<std::uint32_t>{0, 2, 3, 4, 5}));
  EXPECT_EQ(r.reorder.counters().given_up, 1u);
}

TEST(VideoReorder, WithoutAHoldAGapIsGivenUpAtOnce) {
  VideoReorderConfig c;
  c.hold_min_ns = c.hold_max_ns = 0;  // no way to ask again
  Stream r(c);
  r.push(7, 0);
  r.push(9, 0);
  r.poll(0);
  EXPECT_EQ(r.out, (std::vector<std::uint32_t>{7, 9}));
  EXPECT_EQ(r.reorder.counters().given_up, 1u);
}

TEST(VideoReorder, AFarJumpRestartsTheSequenceAndWrapsAreGaps) {
  Stream r;
  r.push(100, 0);
  r.poll(0);
  r.push(5, kMs);  // a restarted encoder
  r.poll(kMs);
  EXPECT_EQ(r.out, (std::vector<std::uint32_t>{100, 5}));
  EXPECT_EQ(r.reorder.counters().restarts, 1u);
  EXPECT_TRUE(r.nacks.empty());
  Stream w;  // across 2^32: 0xFFFFFFFF then 1 is a gap of one (0)
  w.reorder.push(0xFFFF'FFFFu, Bytes{0xFF}, 0);
  w.reorder.push(1, Bytes{1}, 0);
  std::vector<Bytes> ready;
  w.reorder.poll(0, kMs, ready, w.nacks);
  ASSERT_EQ(w.nacks.size(), 1u);
  EXPECT_EQ(w.nacks[0], (proto::VideoNack{0, 1}));
  EXPECT_EQ(ready.size(), 1u);
}

}  // namespace
}  // namespace telex::local
