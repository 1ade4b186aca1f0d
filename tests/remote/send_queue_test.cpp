// SPDX-License-Identifier: MIT
// SendQueue: depth goes before video, a started video frame is finished, each lane keeps its own
// bound and video is dropped (and counted) without touching depth; late packing runs at sending.
#include "telex/remote/send_queue.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace telex::remote {
namespace {

// Items tagged "<lane letter><frame>.<item>", e.g. "d3.0", so the sending order reads as text.
OutFrame frame(char lane, std::uint32_t id, int items, bool trimmable = true) {
  OutFrame f;
  f.frame_id = id;
  f.trimmable = trimmable;
  f.counts_as_frame = lane == 'd';
  for (int i = 0; i < items; ++i) {
    const std::string tag = std::string(1, lane) + std::to_string(id) + "." + std::to_string(i);
    f.items.push_back(std::make_shared<const std::vector<std::uint8_t>>(tag.begin(), tag.end()));
  }
  return f;
}

std::string tag_of(const Buffer& b) { return {b->begin(), b->end()}; }

// Takes up to `n` items; the tags in order, separated by spaces.
std::string drain(SendQueue& q, int n = 1000) {
  std::string out;
  bool done = false, counts = false;
  Lane lane = Lane::Depth;
  for (int i = 0; i < n; ++i) {
    const Buffer b = q.next_item(done, counts, lane);
    if (!b) break;
    const std::string tag = tag_of(b);
    EXPECT_EQ(lane == Lane::Depth, tag[0] != 'v') << tag;
    EXPECT_EQ(counts, tag[0] == 'd') << tag;
    out += (out.empty() ? "" : " ") + tag;
  }
  return out;
}

TEST(SendQueue, DepthGoesBeforeVideoQueuedEarlier) {
  SendQueue q;
  q.push(Lane::Video, frame('v', 1, 2));
  q.push(Lane::Depth, frame('d', 1, 2));
  q.push(Lane::Video, frame('v', 2, 1));
  q.push(Lane::Depth, frame('d', 2, 1));
  EXPECT_EQ(drain(q), "d1.0 d1.1 d2.0 v1.0 v1.1 v2.0");
  EXPECT_TRUE(q.empty());
}

TEST(SendQueue, AStartedVideoFrameFinishesBeforeDepthGoesOn) {
  SendQueue q;
  q.push(Lane::Video, frame('v', 1, 3));
  q.push(Lane::Video, frame('v', 2, 2));
  EXPECT_EQ(drain(q, 1), "v1.0");
  q.push(Lane::Depth, frame('d', 5, 2));
  // v1's fragments stay together; depth then overtakes the video frame not yet started.
  EXPECT_EQ(drain(q), "v1.1 v1.2 d5.0 d5.1 v2.0 v2.1");
}

TEST(SendQueue, FrameDoneMarksTheLastItemOfEachFrame) {
  SendQueue q;
  q.push(Lane::Depth, frame('d', 1, 2));
  bool done = true, counts = false;
  Lane lane = Lane::Video;
  ASSERT_TRUE(q.next_item(done, counts, lane));
  EXPECT_FALSE(done);
  EXPECT_EQ(lane, Lane::Depth);
  ASSERT_TRUE(q.next_item(done, counts, lane));
  EXPECT_TRUE(done);
  EXPECT_TRUE(counts);
  EXPECT_FALSE(q.next_item(done, counts, lane));
}

TEST(SendQueue, VideoOverItsBoundDropsItsOldestAndNeverDepth) {
  SendQueue q(SendQueueLimits{3, 2});
  for (std::uint32_t i = 1; i <= 3; ++i) q.push(Lane::Depth, frame('d', i, 1));
  std::size_t dropped = 0;
  for (std::uint32_t i = 1; i <= 6; ++i) dropped += q.push(Lane::Video, frame('v', i, 2));
  EXPECT_EQ(dropped, 4u);
  EXPECT_EQ(q.counters().video_frames_dropped, 4u);
  EXPECT_EQ(q.counters().depth_frames_dropped, 0u);
  EXPECT_EQ(q.depth_frames(), 3u);
  EXPECT_EQ(drain(q), "d1.0 d2.0 d3.0 v5.0 v5.1 v6.0 v6.1");
}

TEST(SendQueue, TheVideoFrameOnTheWireIsNotDropped) {
  SendQueue q(SendQueueLimits{3, 1});
  q.push(Lane::Video, frame('v', 1, 3));
  EXPECT_EQ(drain(q, 1), "v1.0");
  EXPECT_EQ(q.push(Lane::Video, frame('v', 2, 1)), 0u) << "v1 is being sent; v2 waits";
  EXPECT_EQ(q.push(Lane::Video, frame('v', 3, 1)), 1u) << "v2, not yet started, goes";
  EXPECT_EQ(drain(q), "v1.1 v1.2 v3.0");
}

TEST(SendQueue, DepthKeepsItsBoundWhateverVideoWaits) {
  SendQueue q(SendQueueLimits{2, 4});
  for (std::uint32_t i = 1; i <= 4; ++i) q.push(Lane::Video, frame('v', i, 5));
  EXPECT_EQ(q.push(Lane::Depth, frame('d', 1, 1)), 0u);
  EXPECT_EQ(q.push(Lane::Depth, frame('d', 2, 1)), 0u) << "video does not count against depth";
  // Resends are not counted against the bound and never dropped.
  EXPECT_EQ(q.push(Lane::Depth, frame('r', 9, 1, false)), 0u);
  EXPECT_EQ(q.push(Lane::Depth, frame('d', 3, 1)), 1u) << "the third trimmable depth frame";
  EXPECT_EQ(q.counters().depth_frames_dropped, 1u);
  EXPECT_EQ(q.counters().video_frames_dropped, 0u);
  bool done = false, counts = false;
  Lane lane = Lane::Video;
  std::string order;
  while (const Buffer b = q.next_item(done, counts, lane)) {
    if (lane == Lane::Depth) order += tag_of(b) + " ";
  }
  EXPECT_EQ(order, "d2.0 r9.0 d3.0 ");
}

// Resent tiles and resent pairs (issue 28: pairs asked for by VideoNack) share one bound.
TEST(SendQueue, RepairBytesCountOnlyUnsentResendsInBothLanes) {
  SendQueue q;
  q.push(Lane::Depth, frame('r', 1, 2, false));  // "r1.0", "r1.1": 4 bytes each
  q.push(Lane::Depth, frame('d', 2, 2));
  q.push(Lane::Video, frame('v', 3, 2, false));  // a resent pair: "v3.0", "v3.1"
  q.push(Lane::Video, frame('v', 4, 2));         // a pair sent once: not a resend
  EXPECT_EQ(q.queued_repair_bytes(), 16u);
  EXPECT_EQ(drain(q, 1), "r1.0");
  EXPECT_EQ(q.queued_repair_bytes(), 12u);
  EXPECT_EQ(drain(q, 4), "r1.1 d2.0 d2.1 v3.0");
  EXPECT_EQ(q.queued_repair_bytes(), 4u);
  drain(q);
  EXPECT_EQ(q.queued_repair_bytes(), 0u);
}

// A resent pair is packed late (its ids and seals are those of its sending): until then its
// messages' size stands in for the datagrams it will become; once packed, what is left of them.
TEST(SendQueue, AResentPairNotYetPackedCountsItsMessagesBytes) {
  SendQueue q;
  OutFrame late;
  late.trimmable = false;
  late.counts_as_frame = false;
  late.unpacked_bytes = 5000;
  late.pack = [] { return frame('v', 9, 3).items; };
  q.push(Lane::Video, std::move(late));
  EXPECT_EQ(q.queued_repair_bytes(), 5000u);
  q.push(Lane::Depth, frame('d', 1, 1));
  EXPECT_EQ(drain(q, 1), "d1.0");  // depth first: the pair is still unpacked
  EXPECT_EQ(q.queued_repair_bytes(), 5000u);
  EXPECT_EQ(drain(q, 1), "v9.0");  // packed: two 4-byte items left
  EXPECT_EQ(q.queued_repair_bytes(), 8u);
}

TEST(SendQueue, LatePackingRunsWhenTheFrameIsFirstTaken) {
  SendQueue q;
  int packed_at = -1, taken = 0;
  OutFrame late;
  late.counts_as_frame = false;
  late.pack = [&] {
    packed_at = taken;
    return frame('v', 7, 2).items;
  };
  q.push(Lane::Video, std::move(late));
  q.push(Lane::Depth, frame('d', 1, 2));
  bool done = false, counts = false;
  Lane lane = Lane::Depth;
  std::string order;
  while (const Buffer b = q.next_item(done, counts, lane)) {
    order += tag_of(b) + " ";
    ++taken;
  }
  EXPECT_EQ(order, "d1.0 d1.1 v7.0 v7.1 ");
  EXPECT_EQ(packed_at, 2) << "packed after the depth that overtook it had gone";

  // A late frame that packs to nothing is skipped.
  OutFrame empty;
  empty.pack = [] { return std::vector<Buffer>{}; };
  q.push(Lane::Video, std::move(empty));
  q.push(Lane::Video, frame('v', 8, 1));
  EXPECT_EQ(drain(q), "v8.0");
}

}  // namespace
}  // namespace telex::remote
