// SPDX-License-Identifier: MIT
// Repair of lost tiles (docs/PROTOCOL.md 2.5): what the assembler asks for, what it takes back,
// what it counts as unclosed, and the tile ages it reports.
#include <gtest/gtest.h>

#include <algorithm>

#include "stream_fixtures.h"
#include "telex/local/link/frame_assembler.h"

namespace telex::local {
namespace {

constexpr std::int64_t kMs = 1'000'000;
constexpr std::int64_t kPeriod = 33'333'333;  // fps 30 in stream_config_2x2

cv::Mat1w level(std::uint16_t mm) { return cv::Mat1w(30, 40, mm); }
cv::Rect tile_rect(int i) { return {(i % 2) * 20, (i / 2) * 15, 20, 15}; }

std::vector<proto::EncodedTile> encoded(const cv::Mat1w& frame) {
  return proto::encode_tiles(frame, proto::TileGrid{40, 30, 20, 15}, proto::Codec::Zip);
}

bool tile(FrameAssembler& a, const cv::Mat1w& frame, std::uint32_t id, std::uint16_t index,
          std::int64_t now, bool repair = false) {
  proto::Header h;
  h.frame_id = id;
  h.capture_ns = static_cast<std::uint64_t>(id) * kPeriod;
  h.flags = repair ? proto::kFlagRepair : 0;
  return a.apply_tile(h, proto::tile_message(encoded(frame)[index], proto::Codec::Zip), now);
}

std::optional<AssembledFrame> close(FrameAssembler& a, std::uint32_t id, bool key,
                                    std::vector<std::uint16_t> listed, std::int64_t now) {
  proto::Header h;
  h.frame_id = id;
  h.capture_ns = static_cast<std::uint64_t>(id) * kPeriod;
  return a.finish(
      h, proto::FrameManifest{id, 4, key, key ? std::vector<std::uint16_t>{} : listed, {}}, now);
}

// Frame 1 is a key frame of 1000 mm; frame 2 changes every tile to 1200 mm and tile 3 is lost.
FrameAssembler lost_tile_3(std::int64_t& now) {
  FrameAssembler a(500 * kMs);
  a.configure(test::stream_config_2x2());
  a.set_watched({tile_rect(3)});
  for (std::uint16_t i = 0; i < 4; ++i) EXPECT_TRUE(tile(a, level(1000), 1, i, now));
  EXPECT_TRUE(close(a, 1, true, {}, now));
  now += kPeriod;
  for (std::uint16_t i = 0; i < 3; ++i) EXPECT_TRUE(tile(a, level(1200), 2, i, now));
  return a;
}

TEST(Repair, AWatchedLostTileIsAskedForOnceAndTakenBack) {
  std::int64_t now = 0;
  FrameAssembler a = lost_tile_3(now);
  auto f = close(a, 2, false, {0, 1, 2, 3}, now);
  ASSERT_TRUE(f);
  EXPECT_FALSE(f->complete);
  RepairRequest r = a.repair_request(now, 25 * kMs, 250 * kMs);
  ASSERT_TRUE(r.nack);
  EXPECT_EQ(*r.nack, (proto::TileNack{2, {3}}));
  EXPECT_FALSE(r.key_frame);  // every frame closed
  EXPECT_EQ(a.counters().watched_tiles_nacked, 1u);
  // Asked again only after the retry time.
  EXPECT_FALSE(a.repair_request(now + 10 * kMs, 25 * kMs, 250 * kMs).nack);
  // The repair arrives: the tile is current and the last frame is republished with it.
  EXPECT_TRUE(tile(a, level(1200), 2, 3, now + 12 * kMs, /*repair=*/true));
  auto rep = a.take_repaired(now + 12 * kMs);
  ASSERT_TRUE(rep);
  EXPECT_EQ(rep->part, AssembledPart::Repair);
  EXPECT_EQ(rep->capture_ns, 2 * kPeriod);
  EXPECT_TRUE(rep->complete);
  EXPECT_EQ(rep->changed_since_roi_part, std::vector<cv::Rect>{tile_rect(3)});
  EXPECT_EQ(cv::countNonZero(rep->depth_mm != 1200), 0);
  EXPECT_FALSE(a.take_repaired(now + 13 * kMs));
  EXPECT_EQ(a.counters().tiles_repaired, 1u);
  // Nothing more to ask, and a second copy of the same tile is of no use.
  EXPECT_FALSE(a.repair_request(now + 40 * kMs, 25 * kMs, 250 * kMs).nack);
  EXPECT_FALSE(tile(a, level(1200), 2, 3, now + 14 * kMs, true));
  EXPECT_EQ(a.counters().repairs_useless, 1u);
}

TEST(Repair, AStaleTileIsNotConfirmedByLaterFramesAndExpiresUnrepaired) {
  std::int64_t now = 0;
  FrameAssembler a = lost_tile_3(now);
  ASSERT_TRUE(close(a, 2, false, {0, 1, 2, 3}, now));
  // Frames 3.. change nothing: before repair existed they confirmed tile 3's frame-1 data.
  std::optional<AssembledFrame> f;
  for (std::uint32_t id = 3; id < 20; ++id) {
    now += kPeriod;
    f = close(a, id, false, {}, now);
    ASSERT_TRUE(f);
  }
  EXPECT_EQ(a.counters().tiles_expired, 1u);
  EXPECT_EQ(cv::countNonZero(f->depth_mm(tile_rect(3))), 0);
  // Its age grew a frame period per frame until it expired.
  EXPECT_GE(a.ages().watched.max(), 16.5);
}

TEST(Repair, TilesOutsideTheWatchedOnesAreAskedForTooButRepublishNothing) {
  std::int64_t now = 0;
  FrameAssembler a = lost_tile_3(now);
  a.set_watched({tile_rect(0)});
  ASSERT_TRUE(close(a, 2, false, {0, 1, 2, 3}, now));
  RepairRequest r = a.repair_request(now, 25 * kMs, 250 * kMs);
  ASSERT_TRUE(r.nack);
  EXPECT_EQ(r.nack->tiles, std::vector<std::uint16_t>{3});
  EXPECT_FALSE(r.key_frame);
  // Its copy makes it current, but republishes nothing: no fingertip reads it.
  EXPECT_TRUE(tile(a, level(1200), 2, 3, now + 12 * kMs, /*repair=*/true));
  EXPECT_EQ(a.counters().tiles_repaired, 1u);
  EXPECT_FALSE(a.take_repaired(now + 12 * kMs));
  EXPECT_FALSE(a.repair_request(now + 40 * kMs, 25 * kMs, 250 * kMs).nack);
}

TEST(Repair, UnclosedFramesAskForAKeyFrameAtMostOncePerIntervalUntilOneCloses) {
  std::int64_t now = 0;
  FrameAssembler a = lost_tile_3(now);
  now += kPeriod;
  ASSERT_TRUE(tile(a, level(1300), 3, 0, now));  // frame 2's manifest was lost
  ASSERT_TRUE(close(a, 3, false, {0}, now));
  EXPECT_TRUE(a.repair_request(now, 25 * kMs, 250 * kMs).key_frame);
  now += kPeriod;
  ASSERT_TRUE(close(a, 4, false, {}, now));
  EXPECT_FALSE(a.repair_request(now, 25 * kMs, 250 * kMs).key_frame);  // within the interval
  now += 300 * kMs;
  ASSERT_TRUE(close(a, 5, false, {}, now));
  EXPECT_TRUE(a.repair_request(now, 25 * kMs, 250 * kMs).key_frame);  // the key frame was lost
  // The key frame closes: nothing is wanted any more.
  now += 300 * kMs;
  for (std::uint16_t i = 0; i < 4; ++i) ASSERT_TRUE(tile(a, level(1400), 6, i, now));
  ASSERT_TRUE(close(a, 6, true, {}, now));
  EXPECT_FALSE(a.repair_request(now, 25 * kMs, 250 * kMs).key_frame);
  EXPECT_EQ(a.counters().key_frame_requests, 2u);
}

TEST(Repair, AFrameWhoseManifestIsLostIsUnclosedAndAsksForAKeyFrame) {
  std::int64_t now = 0;
  FrameAssembler a = lost_tile_3(now);
  // Frame 2's manifest never comes; frame 3's tiles do.
  now += kPeriod;
  ASSERT_TRUE(tile(a, level(1300), 3, 0, now));
  EXPECT_EQ(a.counters().frames_unclosed, 1u);
  ASSERT_TRUE(close(a, 3, false, {0}, now));
  EXPECT_TRUE(a.repair_request(now, 25 * kMs, 250 * kMs).key_frame);
}

TEST(Repair, AgesAreInFramePeriodsAtEachClosedFrame) {
  std::int64_t now = 0;
  FrameAssembler a = lost_tile_3(now);
  ASSERT_TRUE(close(a, 2, false, {0, 1, 2, 3}, now));
  // At frame 2: tiles 0..2 are 0 periods old; tile 3 was last current at frame 1, and the key
  // frame's four tiles were sampled at 0 too.
  EXPECT_EQ(a.ages().all.count(), 8u);
  EXPECT_EQ(a.ages().watched.count(), 2u);
  EXPECT_NEAR(a.ages().watched.max(), 1.0, 1e-6);
  EXPECT_NEAR(a.ages().all.quantile(0.5), 0.05, 1e-9);  // the first 0.1-wide bin
}

}  // namespace
}  // namespace telex::local
