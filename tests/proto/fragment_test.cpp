// SPDX-License-Identifier: MIT
// UDP fragmentation and reassembly: size limit, reordering, loss, bounds, timeout, newest wins.
#include "telex/proto/fragment.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>
#include <random>

namespace telex::proto {
namespace {

std::vector<std::uint8_t> message_of(std::size_t n, std::uint8_t seed) {
  std::vector<std::uint8_t> m(n);
  for (std::size_t i = 0; i < n; ++i) m[i] = static_cast<std::uint8_t>(seed + i * 31);
  return m;
}

TEST(Fragment, NoDatagramExceeds1400Bytes) {
  for (std::size_t n : {std::size_t{1}, kFragmentChunkBytes - 1, kFragmentChunkBytes,
                        kFragmentChunkBytes + 1, std::size_t{9636}, std::size_t{614436}}) {
    const auto frags = fragment_message(message_of(n, 1), 7, 3);
    EXPECT_EQ(frags.size(), (n + kFragmentChunkBytes - 1) / kFragmentChunkBytes);
    for (const auto& f : frags) {
      EXPECT_LE(f.size(), kMaxDatagramBytes);
      ASSERT_TRUE(parse_fragment_header(f).has_value());
    }
  }
  EXPECT_THROW(fragment_message({}, 1, 1), std::invalid_argument);
}

TEST(Fragment, HeaderLayout) {
  const auto f = fragment_message(message_of(2000, 0), 0x11223344, 0x55667788);
  ASSERT_EQ(f.size(), 2u);
  const std::uint8_t expect[] = {'T',  'F',  1,    0,    2,    0,    0,    0,    0x44, 0x33,
                                 0x22, 0x11, 0x88, 0x77, 0x66, 0x55, 0xD0, 0x07, 0,    0};
  EXPECT_TRUE(std::equal(std::begin(expect), std::end(expect), f[1].begin()));
  EXPECT_EQ(f[1].size(), kFragmentHeaderSize + 2000 - kFragmentChunkBytes);
}

TEST(Fragment, RejectsInconsistentHeaders) {
  auto f = fragment_message(message_of(3000, 0), 1, 1);
  auto bad = f[0];
  bad[0] = 'X';
  EXPECT_FALSE(parse_fragment_header(bad));
  bad = f[0];
  bad[2] = 3;  // index 3 of 3
  EXPECT_FALSE(parse_fragment_header(bad));
  bad = f[0];
  bad[4] = 5;  // count disagrees with total length
  EXPECT_FALSE(parse_fragment_header(bad));
  bad = f[1];
  bad.pop_back();  // a middle fragment must be full
  EXPECT_FALSE(parse_fragment_header(bad));
  EXPECT_FALSE(parse_fragment_header(std::span(f[0]).first(kFragmentHeaderSize)));
}

TEST(Reassembler, ReassemblesInAnyOrder) {
  const auto msg = message_of(20000, 5);
  auto frags = fragment_message(msg, 9, 1);
  std::mt19937 rng(42);
  for (int trial = 0; trial < 20; ++trial) {
    std::shuffle(frags.begin(), frags.end(), rng);
    Reassembler r;
    std::optional<std::vector<std::uint8_t>> out;
    for (std::size_t i = 0; i < frags.size(); ++i) {
      out = r.push(frags[i], 1000);
      EXPECT_EQ(out.has_value(), i + 1 == frags.size());
    }
    ASSERT_TRUE(out);
    EXPECT_EQ(*out, msg);
    EXPECT_EQ(r.in_flight(), 0u);
    EXPECT_EQ(r.buffered_bytes(), 0u);
  }
}

TEST(Reassembler, CountsDuplicatesAndMalformed) {
  const auto frags = fragment_message(message_of(3000, 1), 1, 1);
  Reassembler r;
  EXPECT_FALSE(r.push(frags[0], 0));
  EXPECT_FALSE(r.push(frags[0], 0));
  EXPECT_EQ(r.counters().duplicates, 1u);
  // Same message id, other total length: the fragments disagree.
  const auto other = fragment_message(message_of(5000, 1), 1, 1);
  EXPECT_FALSE(r.push(other[1], 0));
  EXPECT_EQ(r.counters().malformed, 1u);
  const std::uint8_t junk[] = {1, 2, 3};
  EXPECT_FALSE(r.push(junk, 0));
  EXPECT_EQ(r.counters().malformed, 2u);
  EXPECT_FALSE(r.push(frags[1], 0));
  EXPECT_TRUE(r.push(frags[2], 0));
  EXPECT_EQ(r.counters().completed, 1u);
}

// A resent pair goes twice under one message id (PROTOCOL.md section 4): the message completes
// from the fragments of either copy, once; the rest are duplicates, and nothing counts as lost.
TEST(Reassembler, AMessageSentTwiceCompletesOnceFromEitherCopy) {
  const auto msg = message_of(5000, 3);  // 4 fragments
  const auto frags = fragment_message(msg, 7, 1);
  ASSERT_EQ(frags.size(), 4u);
  Reassembler r;
  int completed = 0;
  // Copy one loses fragment 2; copy two's 2 completes it, and its 3 comes after.
  for (std::size_t i : {0u, 1u, 3u}) completed += r.push(frags[i], 0).has_value();
  for (std::size_t i : {0u, 1u, 2u, 3u}) {
    const auto out = r.push(frags[i], 1);
    if (out) {
      EXPECT_EQ(*out, msg);
    }
    completed += out.has_value();
  }
  EXPECT_EQ(completed, 1);
  EXPECT_EQ(r.in_flight(), 0u);  // copy two's last fragment started no new message
  EXPECT_EQ(r.counters().duplicates, 3u);
  EXPECT_EQ(r.counters().messages_by_fragments[3], 1u);
  EXPECT_EQ(r.counters().lost(), 0u);

  // A one-fragment message twice is handed out once.
  const auto one = fragment_message(message_of(100, 4), 8, 1);
  EXPECT_TRUE(r.push(one[0], 2));
  EXPECT_FALSE(r.push(one[0], 2));
  EXPECT_EQ(r.counters().duplicates, 4u);
  EXPECT_EQ(r.counters().completed, 2u);
  // A later message with a new id goes through.
  EXPECT_TRUE(r.push(fragment_message(message_of(100, 5), 9, 1)[0], 3));
}

TEST(Reassembler, IncompleteMessagesTimeOut) {
  ReassemblerLimits lim;
  lim.timeout_ns = 100;
  Reassembler r(lim);
  const auto frags = fragment_message(message_of(3000, 1), 1, 1);
  EXPECT_FALSE(r.push(frags[0], 1000));
  r.expire(1100);
  EXPECT_EQ(r.in_flight(), 1u);
  r.expire(1101);
  EXPECT_EQ(r.in_flight(), 0u);
  EXPECT_EQ(r.counters().dropped_timeout, 1u);
  EXPECT_FALSE(r.push(frags[1], 1102));  // the rest now starts a new, incomplete message
}

TEST(Reassembler, NewestFrameWins) {
  Reassembler r;
  const auto old_frame = fragment_message(message_of(3000, 1), 1, 10);
  const auto new_frame = fragment_message(message_of(3000, 2), 2, 11);
  EXPECT_FALSE(r.push(old_frame[0], 0));
  for (std::size_t i = 0; i + 1 < new_frame.size(); ++i) EXPECT_FALSE(r.push(new_frame[i], 0));
  EXPECT_TRUE(r.push(new_frame.back(), 0));
  EXPECT_EQ(r.counters().dropped_superseded, 1u);
  EXPECT_EQ(r.in_flight(), 0u);
  // Late fragments of the superseded frame are stale.
  EXPECT_FALSE(r.push(old_frame[1], 0));
  EXPECT_EQ(r.counters().stale, 1u);
  // Other messages of the newest frame are still welcome.
  const auto sibling = fragment_message(message_of(100, 3), 3, 11);
  EXPECT_TRUE(r.push(sibling[0], 0));
}

TEST(Reassembler, FrameIdsCompareAcrossWrap) {
  Reassembler r;
  const auto before = fragment_message(message_of(10, 1), 1, 0xFFFFFFFFu);
  const auto after = fragment_message(message_of(10, 2), 2, 0);
  EXPECT_TRUE(r.push(before[0], 0));
  EXPECT_TRUE(r.push(after[0], 0));  // 0 follows 0xFFFFFFFF
  EXPECT_FALSE(r.push(fragment_message(message_of(10, 3), 3, 0xFFFFFFFEu)[0], 0));
  EXPECT_EQ(r.counters().stale, 1u);
}

TEST(Reassembler, StaysWithinItsBoundsEvictingTheOldestFrame) {
  ReassemblerLimits lim;
  lim.max_in_flight = 4;
  lim.max_buffered_bytes = 4 * 3000;
  lim.max_message_bytes = 3000;
  Reassembler r(lim);
  for (std::uint32_t id = 0; id < 10; ++id) {
    const auto f = fragment_message(message_of(3000, 1), id, id);
    EXPECT_FALSE(r.push(f[0], 0));
    EXPECT_LE(r.in_flight(), 4u);
    EXPECT_LE(r.buffered_bytes(), lim.max_buffered_bytes);
  }
  EXPECT_EQ(r.counters().dropped_bound, 6u);
  // The survivors are the newest four frames: completing frame 9 works.
  const auto f9 = fragment_message(message_of(3000, 1), 9, 9);
  EXPECT_FALSE(r.push(f9[1], 0));
  EXPECT_TRUE(r.push(f9[2], 0));
  // A message larger than the bound is refused outright.
  const auto big = fragment_message(message_of(3001, 1), 50, 50);
  EXPECT_FALSE(r.push(big[0], 0));
  EXPECT_EQ(r.counters().malformed, 1u);
}

// The receiver's loss count: fragments missing from messages it saw part of, plus message ids it
// never saw, against the datagrams a seeded lossy link dropped. One-fragment messages make it
// exact; a message lost whole counts once whatever its size.
TEST(Reassembler, CountsWhatTheLinkLost) {
  std::mt19937 rng(5);
  std::bernoulli_distribution lose(0.2);
  Reassembler r;
  std::uint64_t dropped = 0, dropped_whole_extra = 0;
  std::uint32_t id = 100;
  for (std::uint32_t frame = 1; frame <= 200; ++frame) {
    for (int m = 0; m < 6; ++m, ++id) {
      // Mostly one-fragment tiles, some of three fragments.
      const auto frags = fragment_message(message_of(m == 5 ? 3000 : 300, 1), id, frame);
      std::size_t lost_here = 0;
      for (const auto& f : frags) {
        if (lose(rng)) {
          ++lost_here;
          continue;
        }
        r.push(f, frame * 1000);
      }
      dropped += lost_here;
      if (lost_here == frags.size()) dropped_whole_extra += lost_here - 1;
    }
  }
  r.expire(~0ull);  // what is still in flight at the end is lost too
  // The last message of the run, if lost, is never known: nothing came after it.
  EXPECT_GT(dropped, 200u);
  EXPECT_LE(r.counters().lost() + dropped_whole_extra, dropped);
  EXPECT_GE(r.counters().lost() + dropped_whole_extra + 3, dropped);
  EXPECT_GT(r.counters().messages_unseen, 0u);
  EXPECT_GT(r.counters().fragments_missing, 0u);

  // A late message is not counted twice; a restarted sender does not count as loss.
  Reassembler s;
  s.push(fragment_message(message_of(10, 1), 1, 1)[0], 0);
  s.push(fragment_message(message_of(10, 1), 3, 1)[0], 0);
  EXPECT_EQ(s.counters().messages_unseen, 1u);
  s.push(fragment_message(message_of(10, 1), 2, 1)[0], 0);
  s.push(fragment_message(message_of(10, 1), 4, 1)[0], 0);
  EXPECT_EQ(s.counters().messages_unseen, 1u);
  s.push(fragment_message(message_of(10, 1), 0x8000'0000u, 2)[0], 0);
  s.push(fragment_message(message_of(10, 1), 0, 3)[0], 0);
  EXPECT_EQ(s.counters().messages_unseen, 1u);
}

}  // namespace
}  // namespace telex::proto
