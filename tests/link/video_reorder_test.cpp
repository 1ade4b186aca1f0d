// SPDX-License-Identifier: MIT
// VideoReorder: pairs leave in encode_seq order; a gap is NACKed at once, again after the retry
// interval, and given up at its deadline; what comes late is dropped and counted.
#include "telex/local/link/video_reorder.h"

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
  void push(std::uint32_t seq, std::int64_t now_ns, bool resent = false) {
    reorder.push(seq, pair_bytes(seq), now_ns, resent);
  }
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
  // Nothing waits but the next pair: overdue 33 ms + 16.5 ms after the newest came.
  EXPECT_EQ(r.reorder.next_wake_ns(kMs), 14 * 33 * kMs + 49'500'000);
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
  // The retry interval is max(12 ms, 2 RTT + 2 ms): 12 ms at a 2 ms round trip, past the
  // remote's 10 ms dedup interval.
  EXPECT_EQ(r.reorder.next_wake_ns(2 * kMs), 22 * kMs);
  r.poll(21 * kMs, 2 * kMs);
  EXPECT_EQ(r.nacks.size(), 1u);
  r.poll(22 * kMs, 2 * kMs);
  r.poll(34 * kMs, 2 * kMs);
  r.poll(46 * kMs, 2 * kMs);  // the limit: three asks
  r.poll(80 * kMs, 2 * kMs);
  EXPECT_EQ(r.nacks.size(), 3u);
  EXPECT_EQ(r.reorder.counters().nacks, 3u);
  EXPECT_EQ(r.out, (std::vector<std::uint32_t>{5}));
}

TEST(VideoReorder, AGapPastItsDeadlineIsGivenUpAndLateCopiesAreDropped) {
  Stream r;  // 1 ms round trip: the deadline is max(30 ms, 3 RTT + 10 ms) = 30 ms after the gap
  r.push(1, 0);
  r.push(3, 33 * kMs);
  r.poll(33 * kMs);
  EXPECT_EQ(r.reorder.next_wake_ns(kMs), 33 * kMs + 12 * kMs);  // the retry comes first
  r.poll(62 * kMs);
  EXPECT_EQ(r.out, (std::vector<std::uint32_t>{1}));
  r.poll(63 * kMs);
  EXPECT_EQ(r.out, (std::vector<std::uint32_t>{1, 3}));
  EXPECT_EQ(r.reorder.counters().given_up, 1u);
  r.push(2, 60 * kMs);
  r.poll(60 * kMs);
  EXPECT_EQ(r.reorder.counters().late, 1u);
  EXPECT_EQ(r.out.size(), 2u);
  EXPECT_EQ(r.reorder.next_wake_ns(kMs), 0);
}

// Asking sooner: after pairs every 33 ms, the next one is overdue 49.5 ms after the newest came
// (the median interval plus half of it) and asked for once, a period before the pair behind it
// would show the gap. When that pair comes the gap is known: the retries go on from the overdue
// NACK, and the resend is a repair.
// An overdue pair is asked for, and again every retry interval (its copy can be lost too); a
// later pair that shows the gap starts its retries afresh. A copy keeps the pairs' schedule:
// the pair after it is overdue an interval after the copy's pair was due.
TEST(VideoReorder, AnOverduePairIsAskedForAgainUntilItOrALaterPairComes) {
  Stream r;
  for (std::uint32_t s = 0; s <= 5; ++s) {
    r.push(s, s * 33 * kMs);
    r.poll(s * 33 * kMs);
  }
  const std::int64_t newest_ns = 5 * 33 * kMs;
  EXPECT_EQ(r.reorder.overdue_ns(), 49'500'000);
  r.poll(newest_ns + 49 * kMs);
  EXPECT_TRUE(r.nacks.empty());
  r.poll(newest_ns + 50 * kMs);  // 6 is overdue
  ASSERT_EQ(r.nacks.size(), 1u);
  EXPECT_EQ(r.nacks[0], (proto::VideoNack{6, 1}));
  EXPECT_EQ(r.reorder.counters().asked_overdue, 1u);
  r.poll(newest_ns + 61 * kMs);  // not before the retry interval (12 ms) ...
  EXPECT_EQ(r.nacks.size(), 1u);
  r.poll(newest_ns + 62 * kMs);  // ... then again: the copy may have been lost
  ASSERT_EQ(r.nacks.size(), 2u);
  EXPECT_EQ(r.nacks[1], (proto::VideoNack{6, 1}));
  r.push(7, 7 * 33 * kMs);  // the gap shows: 7 waits; the retries go on from the last NACK
  r.poll(7 * 33 * kMs);
  EXPECT_EQ(r.nacks.size(), 2u);
  r.poll(newest_ns + 74 * kMs);
  ASSERT_EQ(r.nacks.size(), 3u);
  EXPECT_EQ(r.nacks[2], (proto::VideoNack{6, 1}));
  EXPECT_EQ(r.out.size(), 6u);
  r.push(6, newest_ns + 75 * kMs, /*resent=*/true);
  r.poll(newest_ns + 75 * kMs);
  EXPECT_EQ(r.out, (std::vector<std::uint32_t>{0, 1, 2, 3, 4, 5, 6, 7}));
  EXPECT_EQ(r.reorder.counters().repaired, 1u);
  EXPECT_EQ(r.reorder.counters().asked_overdue, 1u);
  // 8 is lost too; the remote's copy, asked for as overdue, comes before 9: a repair.
  const std::int64_t seven_ns = 7 * 33 * kMs;
  r.poll(seven_ns + 50 * kMs);
  ASSERT_EQ(r.nacks.size(), 4u);
  EXPECT_EQ(r.nacks[3], (proto::VideoNack{8, 1}));
  r.push(8, seven_ns + 51 * kMs, /*resent=*/true);
  r.poll(seven_ns + 51 * kMs);
  EXPECT_EQ(r.out.back(), 8u);
  EXPECT_EQ(r.reorder.counters().repaired, 2u);
  EXPECT_EQ(r.reorder.counters().held, 1u);  // only 7 waited
  // 8 was due at 7 + 33 ms: 9 is overdue 49.5 ms after that, not after the copy came. The
  // copy's 51 ms is no interval either.
  EXPECT_EQ(r.reorder.overdue_ns(), 49'500'000);
  r.poll(seven_ns + 82 * kMs);
  EXPECT_EQ(r.nacks.size(), 4u);
  r.poll(seven_ns + 83 * kMs);
  ASSERT_EQ(r.nacks.size(), 5u);
  EXPECT_EQ(r.nacks[4], (proto::VideoNack{9, 1}));
}

// A stream starts with its largest pairs, the ones most often lost: the interval is known from
// the pairs that came, per pair between them, so the first pairs are asked for when overdue too.
TEST(VideoReorder, PairsLostAsTheStreamStartsStillTellTheInterval) {
  Stream r;
  r.push(0, 0);
  r.poll(0);
  EXPECT_EQ(r.reorder.overdue_ns(), 0);  // no interval yet
  r.push(3, 99 * kMs);                   // 1 and 2 lost: 33 ms a pair
  r.poll(99 * kMs);
  EXPECT_EQ(r.reorder.overdue_ns(), 0);  // one interval is not a median
  r.push(1, 100 * kMs, /*resent=*/true);
  r.push(2, 100 * kMs, /*resent=*/true);
  r.push(4, 132 * kMs);
  r.poll(132 * kMs);
  EXPECT_EQ(r.out, (std::vector<std::uint32_t>{0, 1, 2, 3, 4}));
  EXPECT_EQ(r.reorder.overdue_ns(), 49'500'000);
  const std::size_t before = r.nacks.size();
  r.poll(181 * kMs);
  EXPECT_EQ(r.nacks.size(), before);
  r.poll(182 * kMs);  // 5 is overdue
  ASSERT_EQ(r.nacks.size(), before + 1);
  EXPECT_EQ(r.nacks.back(), (proto::VideoNack{5, 1}));
}

// A pair that was only late comes after its overdue NACK and goes straight through, neither
// held nor counted as a repair; a copy the remote sent on that NACK is dropped as late. Fast
// pairs are overdue no sooner than 10 ms after their interval; without ask_overdue never.
TEST(VideoReorder, AnOverduePairThatWasOnlyLateGoesThroughAndTheSlackHasAFloor) {
  Stream r;
  for (std::uint32_t s = 0; s <= 4; ++s) {
    r.push(s, s * 10 * kMs);
    r.poll(s * 10 * kMs);
  }
  EXPECT_EQ(r.reorder.overdue_ns(), 20 * kMs);  // 10 ms + max(5 ms, 10 ms)
  r.poll(60 * kMs);
  ASSERT_EQ(r.nacks.size(), 1u);
  r.push(5, 65 * kMs);
  r.poll(65 * kMs);
  EXPECT_EQ(r.out, (std::vector<std::uint32_t>{0, 1, 2, 3, 4, 5}));
  EXPECT_EQ(r.reorder.counters().repaired, 0u);
  EXPECT_EQ(r.reorder.counters().held, 0u);
  r.push(5, 66 * kMs);  // the remote's copy
  r.poll(66 * kMs);
  EXPECT_EQ(r.reorder.counters().late, 1u);
  EXPECT_EQ(r.nacks.size(), 1u);

  VideoReorderConfig off;
  off.ask_overdue = false;
  Stream quiet(off);
  for (std::uint32_t s = 0; s <= 4; ++s) quiet.push(s, s * 10 * kMs);
  quiet.poll(500 * kMs);
  EXPECT_TRUE(quiet.nacks.empty());
  EXPECT_EQ(quiet.reorder.next_wake_ns(kMs), 0);
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
