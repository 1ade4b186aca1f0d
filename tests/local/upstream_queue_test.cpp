// SPDX-License-Identifier: MIT
// The station's upstream queue (issue 49): a head command replaces one still waiting, never the
// message being written, and the queue stays bounded.
#include "upstream_queue.h"

#include <gtest/gtest.h>

namespace telex::local {
namespace {

std::vector<std::uint8_t> msg(std::uint8_t id) { return {id}; }

TEST(UpstreamQueue, AHeadCommandReplacesTheWaitingOneNeverTheOneInFlight) {
  UpstreamQueue q;
  EXPECT_EQ(q.push(msg(1), true, false), 0u);  // written at once: in flight
  EXPECT_EQ(q.push(msg(2), false, true), 0u);  // a NACK waits
  EXPECT_EQ(q.push(msg(3), true, true), 0u);   // a head command waits
  EXPECT_EQ(q.push(msg(4), true, true), 1u);   // replaces 3, not 1 (in flight)
  ASSERT_EQ(q.size(), 3u);
  EXPECT_EQ(q.front(), msg(1));
  q.pop_front();
  EXPECT_EQ(q.front(), msg(2));
  q.pop_front();
  EXPECT_EQ(q.front(), msg(4));
}

TEST(UpstreamQueue, PastItsBoundTheOldestWaitingGoes) {
  UpstreamQueue q;
  q.push(msg(0), false, false);
  std::size_t dropped = 0;
  for (int i = 1; i <= 100; ++i) dropped += q.push(msg(static_cast<std::uint8_t>(i)), false, true);
  EXPECT_EQ(q.size(), UpstreamQueue::kMaxQueued);
  EXPECT_EQ(dropped, 101 - UpstreamQueue::kMaxQueued);
  EXPECT_EQ(q.front(), msg(0)) << "the message in flight stays";
}

}  // namespace
}  // namespace telex::local
