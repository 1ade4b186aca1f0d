// SPDX-License-Identifier: MIT
// The station's upstream queue (issue 49): a head command (or a probe) replaces one still waiting,
// never the message being written, and the queue stays bounded.
#include "upstream_queue.h"

#include <gtest/gtest.h>

namespace telex::local {
namespace {

std::vector<std::uint8_t> msg(std::uint8_t id) { return {id}; }

TEST(UpstreamQueue, AHeadCommandReplacesTheWaitingOneNeverTheOneInFlight) {
  UpstreamQueue q;
  EXPECT_EQ(q.push(msg(1), UpstreamQueue::Kind::Head, false), 0u);  // written at once: in flight
  EXPECT_EQ(q.push(msg(2), UpstreamQueue::Kind::Kept, true), 0u);   // a NACK waits
  EXPECT_EQ(q.push(msg(3), UpstreamQueue::Kind::Head, true), 0u);   // a head command waits
  EXPECT_EQ(q.push(msg(4), UpstreamQueue::Kind::Head, true), 1u);   // replaces 3, not 1 (in flight)
  ASSERT_EQ(q.size(), 3u);
  EXPECT_EQ(q.front(), msg(1));
  q.pop_front();
  EXPECT_EQ(q.front(), msg(2));
  q.pop_front();
  EXPECT_EQ(q.front(), msg(4));
}

// The link's liveness probes (every 10 ms): only the newest waiting one goes, uncounted, and it
// never displaces a head command or another message.
TEST(UpstreamQueue, AProbeReplacesTheWaitingProbeOnly) {
  using Kind = UpstreamQueue::Kind;
  UpstreamQueue q;
  EXPECT_EQ(q.push(msg(1), Kind::Probe, false), 0u);  // in flight
  EXPECT_EQ(q.push(msg(2), Kind::Head, true), 0u);
  EXPECT_EQ(q.push(msg(3), Kind::Probe, true), 0u);
  EXPECT_EQ(q.push(msg(4), Kind::Probe, true), 0u);  // replaces 3, not counted
  EXPECT_EQ(q.push(msg(5), Kind::Kept, true), 0u);
  ASSERT_EQ(q.size(), 4u);
  for (std::uint8_t id : {1, 2, 4, 5}) {
    EXPECT_EQ(q.front(), msg(id));
    q.pop_front();
  }
}

TEST(UpstreamQueue, PastItsBoundTheOldestWaitingGoes) {
  UpstreamQueue q;
  q.push(msg(0), UpstreamQueue::Kind::Kept, false);
  std::size_t dropped = 0;
  for (int i = 1; i <= 100; ++i)
    dropped += q.push(msg(static_cast<std::uint8_t>(i)), UpstreamQueue::Kind::Kept, true);
  EXPECT_EQ(q.size(), UpstreamQueue::kMaxQueued);
  EXPECT_EQ(dropped, 101 - UpstreamQueue::kMaxQueued);
  EXPECT_EQ(q.front(), msg(0)) << "the message in flight stays";
}

}  // namespace
}  // namespace telex::local
