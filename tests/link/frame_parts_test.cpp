// SPDX-License-Identifier: MIT
// Frames sent in two parts (ROI tiles first, then the rest): the assembler publishes the ROI part
// at once and completes the same frame when its rest arrives, with the usual missing-tile, ageing
// and staleness rules.
#include <gtest/gtest.h>

#include <algorithm>

#include "stream_fixtures.h"
#include "telex/local/link/frame_assembler.h"

namespace telex::local {
namespace {

constexpr std::int64_t kMs = 1'000'000;

proto::StreamConfig config_2x2() { return test::stream_config_2x2(); }

cv::Mat1w level(std::uint16_t mm) { return cv::Mat1w(30, 40, mm); }

cv::Rect tile_rect(int i) { return {(i % 2) * 20, (i / 2) * 15, 20, 15}; }

// Decodes tiles `which` of `frame` into the assembler as messages of frame `id`.
void tiles(FrameAssembler& a, const cv::Mat1w& frame, std::uint32_t id,
           const std::vector<std::uint16_t>& which, std::int64_t now) {
  const proto::TileGrid grid{40, 30, 20, 15};
  proto::Header h;
  h.frame_id = id;
  for (const auto& t : proto::encode_tiles(frame, grid, proto::Codec::Zip)) {
    if (std::find(which.begin(), which.end(), t.index) == which.end()) continue;
    EXPECT_TRUE(a.apply_tile(h, proto::tile_message(t, proto::Codec::Zip), now))
        << "frame " << id << " tile " << t.index;
  }
}

std::optional<AssembledFrame> manifest(FrameAssembler& a, std::uint32_t id, bool roi_part, bool key,
                                       std::vector<std::uint16_t> listed, std::int64_t now) {
  proto::Header h;
  h.frame_id = id;
  h.capture_ns = 1000 + id;
  h.flags = roi_part ? proto::kFlagRoiPart : 0;
  return a.finish(
      h, proto::FrameManifest{id, 4, key, key ? std::vector<std::uint16_t>{} : listed, {}}, now);
}

double diff(const cv::Mat1w& a, const cv::Mat1w& b) { return cv::norm(a, b, cv::NORM_INF); }

TEST(FrameParts, RoiPartIsPublishedAtOnceAndTheRestCompletesTheSameFrame) {
  FrameAssembler a(500 * kMs);
  a.configure(config_2x2());
  tiles(a, level(1000), 1, {0, 1, 2, 3}, 0);
  ASSERT_TRUE(manifest(a, 1, false, true, {}, 1 * kMs));

  // Frame 2: the ROI is tile 0. Its part is a frame of its own, at once: tile 0 new, the others
  // still frame 1's.
  tiles(a, level(1200), 2, {0}, 30 * kMs);
  auto roi = manifest(a, 2, true, false, {0}, 31 * kMs);
  ASSERT_TRUE(roi);
  EXPECT_EQ(roi->part, AssembledPart::RoiPart);
  EXPECT_TRUE(roi->complete);
  EXPECT_EQ(roi->capture_ns, 1002);
  EXPECT_EQ(diff(roi->depth_mm(tile_rect(0)), level(1200)(tile_rect(0))), 0.0);
  for (int i : {1, 2, 3})
    EXPECT_EQ(diff(roi->depth_mm(tile_rect(i)), level(1000)(tile_rect(i))), 0.0);

  // The rest: tiles 1 and 2 changed, 3 did not. Its tiles are not stale although the frame id
  // was already published; its manifest lists both parts' tiles.
  tiles(a, level(1200), 2, {1, 2}, 35 * kMs);
  auto rest = manifest(a, 2, false, false, {0, 1, 2}, 36 * kMs);
  ASSERT_TRUE(rest);
  EXPECT_EQ(rest->part, AssembledPart::Rest);
  EXPECT_TRUE(rest->complete);
  EXPECT_EQ(rest->frame_id, 2u);
  EXPECT_EQ(rest->changed_since_roi_part, (std::vector<cv::Rect>{tile_rect(1), tile_rect(2)}));
  for (int i : {0, 1, 2})
    EXPECT_EQ(diff(rest->depth_mm(tile_rect(i)), level(1200)(tile_rect(i))), 0.0);
  EXPECT_EQ(diff(rest->depth_mm(tile_rect(3)), level(1000)(tile_rect(3))), 0.0);
  EXPECT_EQ(a.counters().frames, 2u);
  EXPECT_EQ(a.counters().roi_parts, 1u);
  EXPECT_EQ(a.counters().tiles_stale, 0u);

  // Once closed, the frame takes nothing more: a second rest, or its tiles, are stale.
  EXPECT_FALSE(manifest(a, 2, false, false, {0}, 40 * kMs));
  proto::Header h;
  h.frame_id = 2;
  const auto enc =
      proto::encode_tiles(level(1300), proto::TileGrid{40, 30, 20, 15}, proto::Codec::Zip);
  EXPECT_FALSE(a.apply_tile(h, proto::DepthTile{3, 20, 15, 20, 15, proto::Codec::Zip, enc[3].bytes},
                            41 * kMs));
  EXPECT_EQ(a.counters().tiles_stale, 1u);
}

TEST(FrameParts, KeyFrameInPartsAndMissingTilesCountOnceWhenTheFrameCloses) {
  FrameAssembler a(500 * kMs);
  a.configure(config_2x2());
  // Key frame in parts: the ROI part lists its tiles (an ROI part never claims a key frame).
  tiles(a, level(900), 1, {3}, 0);
  auto roi = manifest(a, 1, true, false, {3}, 1 * kMs);
  ASSERT_TRUE(roi);
  // Nothing else has arrived yet: no data there, not a guess.
  for (int i : {0, 1, 2}) EXPECT_EQ(cv::countNonZero(roi->depth_mm(tile_rect(i))), 0);
  EXPECT_EQ(diff(roi->depth_mm(tile_rect(3)), level(900)(tile_rect(3))), 0.0);
  // The rest loses tile 1.
  tiles(a, level(900), 1, {0, 2}, 5 * kMs);
  auto rest = manifest(a, 1, false, true, {}, 6 * kMs);
  ASSERT_TRUE(rest);
  EXPECT_EQ(rest->part, AssembledPart::Rest);
  EXPECT_FALSE(rest->complete);
  EXPECT_EQ(a.counters().tiles_missing, 1u);
  EXPECT_EQ(a.counters().frames_incomplete, 1u);
  EXPECT_EQ(cv::countNonZero(rest->depth_mm(tile_rect(1))), 0);

  // An ROI part that says key frame is malformed; so is a second ROI part of the same frame.
  EXPECT_FALSE(manifest(a, 2, true, true, {}, 10 * kMs));
  tiles(a, level(950), 2, {0}, 10 * kMs);
  ASSERT_TRUE(manifest(a, 2, true, false, {0}, 11 * kMs));
  EXPECT_FALSE(manifest(a, 2, true, false, {0}, 12 * kMs));
}

TEST(FrameParts, RoiPartsDoNotConfirmTheRestAndALateRestIsStale) {
  FrameAssembler a(100 * kMs);
  a.configure(config_2x2());
  tiles(a, level(1000), 1, {0, 1, 2, 3}, 0);
  ASSERT_TRUE(manifest(a, 1, false, true, {}, 0));
  // Frame 2 in one part at 90 ms, nothing changed: every tile confirmed then.
  ASSERT_TRUE(manifest(a, 2, false, false, {}, 90 * kMs));
  // Frame 3's ROI part (tile 0) at 150 ms; its rest is lost.
  tiles(a, level(1100), 3, {0}, 150 * kMs);
  auto f3 = manifest(a, 3, true, false, {0}, 150 * kMs);
  ASSERT_TRUE(f3);
  EXPECT_EQ(cv::countNonZero(f3->depth_mm), 40 * 30);  // 60 ms old: still trusted
  // Frame 4's ROI part at 200 ms: tiles 1..3 were last confirmed at 90 ms, beyond the 100 ms
  // limit, because ROI parts confirm only their own tiles.
  tiles(a, level(1100), 4, {0}, 200 * kMs);
  auto f4 = manifest(a, 4, true, false, {0}, 200 * kMs);
  ASSERT_TRUE(f4);
  EXPECT_EQ(diff(f4->depth_mm(tile_rect(0)), level(1100)(tile_rect(0))), 0.0);
  for (int i : {1, 2, 3}) EXPECT_EQ(cv::countNonZero(f4->depth_mm(tile_rect(i))), 0);
  EXPECT_EQ(a.counters().tiles_expired, 3u);
  // Frame 3's rest, arriving after frame 4's ROI part, is stale: tiles and manifest.
  proto::Header h;
  h.frame_id = 3;
  const auto enc =
      proto::encode_tiles(level(1100), proto::TileGrid{40, 30, 20, 15}, proto::Codec::Zip);
  EXPECT_FALSE(a.apply_tile(h, proto::DepthTile{1, 20, 0, 20, 15, proto::Codec::Zip, enc[1].bytes},
                            201 * kMs));
  EXPECT_FALSE(manifest(a, 3, false, false, {0, 1}, 201 * kMs));
  // Frame 4's rest brings tiles 1..3 back.
  tiles(a, level(1100), 4, {1, 2, 3}, 210 * kMs);
  auto rest = manifest(a, 4, false, false, {0, 1, 2, 3}, 210 * kMs);
  ASSERT_TRUE(rest);
  EXPECT_EQ(diff(rest->depth_mm, level(1100)), 0.0);
  EXPECT_EQ(rest->changed_since_roi_part.size(), 3u);
}

}  // namespace
}  // namespace telex::local
