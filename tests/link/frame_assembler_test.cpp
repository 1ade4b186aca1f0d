// SPDX-License-Identifier: MIT
// Frame reassembly from tiles: whole frames, skipped unchanged tiles, missing and expired tiles.
#include "telex/local/link/frame_assembler.h"

#include <gtest/gtest.h>

#include "stream_fixtures.h"

namespace telex::local {
namespace {

constexpr std::int64_t kMs = 1'000'000;

proto::StreamConfig small_config() { return test::stream_config_2x2(); }

cv::Mat1w ramp(int w, int h, int offset) {
  cv::Mat1w m(h, w);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) m(y, x) = static_cast<std::uint16_t>(800 + offset + x + 3 * y);
  return m;
}

// Sends the tiles whose index is in `which` (all when empty) and returns the manifest.
proto::FrameManifest send(FrameAssembler& a, const cv::Mat1w& frame, std::uint32_t frame_id,
                          std::vector<std::uint16_t> which, bool key, std::int64_t now,
                          std::vector<std::uint16_t> drop = {}) {
  const proto::TileGrid grid{frame.cols, frame.rows, 20, 15};
  proto::Header h;
  h.frame_id = frame_id;
  for (const auto& t : proto::encode_tiles(frame, grid, proto::Codec::Zip)) {
    const bool wanted = key || std::find(which.begin(), which.end(), t.index) != which.end();
    const bool dropped = std::find(drop.begin(), drop.end(), t.index) != drop.end();
    if (!wanted || dropped) continue;
    EXPECT_TRUE(a.apply_tile(h, proto::tile_message(t, proto::Codec::Zip), now));
  }
  proto::FrameManifest m;
  m.frame_id = frame_id;
  m.tile_count = static_cast<std::uint16_t>(grid.count());
  m.key_frame = key;
  if (!key) m.changed_tiles = which;
  return m;
}

TEST(FrameAssembler, KeyFrameThenDeltaRebuildsSenderFrame) {
  FrameAssembler a(500 * kMs);
  a.configure(small_config());
  const cv::Mat1w f1 = ramp(40, 30, 0);
  proto::Header h;
  h.frame_id = 1;
  h.capture_ns = 123;
  auto out = a.finish(h, send(a, f1, 1, {}, true, 10 * kMs), 11 * kMs);
  ASSERT_TRUE(out);
  EXPECT_TRUE(out->complete);
  EXPECT_EQ(cv::norm(out->depth_mm, f1, cv::NORM_INF), 0.0);
  EXPECT_EQ(out->capture_ns, 123);
  EXPECT_DOUBLE_EQ(out->intrinsics.fx, 50);

  // Frame 2 changes only tile 3; the others are skipped by the sender and must persist.
  cv::Mat1w f2 = f1.clone();
  f2(cv::Rect(20, 15, 20, 15)).setTo(1500);
  h.frame_id = 2;
  out = a.finish(h, send(a, f2, 2, {3}, false, 40 * kMs), 41 * kMs);
  ASSERT_TRUE(out);
  EXPECT_TRUE(out->complete);
  EXPECT_EQ(cv::norm(out->depth_mm, f2, cv::NORM_INF), 0.0);
  EXPECT_EQ(a.counters().frames, 2u);
}

TEST(FrameAssembler, MissingTileKeepsLastValueThenExpires) {
  FrameAssembler a(100 * kMs);
  a.configure(small_config());
  const cv::Mat1w f1 = ramp(40, 30, 0);
  const cv::Mat1w f2 = ramp(40, 30, 7);
  proto::Header h;
  h.frame_id = 1;
  ASSERT_TRUE(a.finish(h, send(a, f1, 1, {}, true, 0), 1 * kMs));
  // Frame 2 is a key frame but tile 0 is lost: it keeps frame 1's values.
  h.frame_id = 2;
  auto out = a.finish(h, send(a, f2, 2, {}, true, 30 * kMs, {0}), 31 * kMs);
  ASSERT_TRUE(out);
  EXPECT_FALSE(out->complete);
  EXPECT_EQ(a.counters().tiles_missing, 1u);
  const cv::Rect t0(0, 0, 20, 15);
  EXPECT_EQ(cv::norm(out->depth_mm(t0), f1(t0), cv::NORM_INF), 0.0);
  EXPECT_EQ(
      cv::norm(out->depth_mm(cv::Rect(20, 0, 20, 15)), f2(cv::Rect(20, 0, 20, 15)), cv::NORM_INF),
      0.0);
  // Tile 0 keeps being lost: after 100 ms it becomes no data, the rest stays.
  h.frame_id = 3;
  out = a.finish(h, send(a, f2, 3, {}, true, 150 * kMs, {0}), 151 * kMs);
  ASSERT_TRUE(out);
  EXPECT_EQ(cv::countNonZero(out->depth_mm(t0)), 0);
  EXPECT_EQ(cv::countNonZero(out->depth_mm(cv::Rect(20, 0, 20, 15))), 300);
  EXPECT_EQ(a.counters().tiles_expired, 1u);
}

TEST(FrameAssembler, RejectsStaleAndMisplacedTiles) {
  FrameAssembler a;
  proto::Header h;
  proto::DepthTile t;
  EXPECT_FALSE(a.apply_tile(h, t, 0));  // not configured
  a.configure(small_config());
  const cv::Mat1w f = ramp(40, 30, 0);
  h.frame_id = 5;
  ASSERT_TRUE(a.finish(h, send(a, f, 5, {}, true, 0), 0));
  // A tile of an older frame, and a tile whose rectangle disagrees with the grid.
  const auto tiles = proto::encode_tiles(f, proto::TileGrid{40, 30, 20, 15}, proto::Codec::Zip);
  h.frame_id = 4;
  proto::DepthTile old{0, 0, 0, 20, 15, proto::Codec::Zip, tiles[0].bytes};
  EXPECT_FALSE(a.apply_tile(h, old, 0));
  EXPECT_EQ(a.counters().tiles_stale, 1u);
  h.frame_id = 6;
  proto::DepthTile moved{0, 20, 0, 20, 15, proto::Codec::Zip, tiles[0].bytes};
  EXPECT_FALSE(a.apply_tile(h, moved, 0));
  proto::DepthTile garbage{1, 20, 0, 20, 15, proto::Codec::Zip, {1, 2, 3}};
  EXPECT_FALSE(a.apply_tile(h, garbage, 0));
  EXPECT_EQ(a.counters().tiles_rejected, 3u);  // unconfigured, moved, garbage
  // An old manifest produces nothing.
  proto::FrameManifest m{4, 4, true, {}, {}};
  h.frame_id = 4;
  EXPECT_FALSE(a.finish(h, m, 0));
}

}  // namespace
}  // namespace telex::local
