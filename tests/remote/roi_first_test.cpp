// SPDX-License-Identifier: MIT
// ROI-first processing: the ROI part carries exactly the ROI tiles, the rest follows on frames
// where it is due, a receiver holding both parts holds the sender's frame, and frames without
// the rest due leave every pixel outside the ROI tiles alone.
#include <gtest/gtest.h>

#include <algorithm>
#include <functional>
#include <random>

#include "remote_frames.h"
#include "telex/proto/depth_codec.h"
#include "telex/remote/pipeline.h"

namespace telex::remote {
namespace {

using test::frame_of;

// A tilted surface with noise and holes of several sizes: the spatial fill needs several passes
// and reaches across tile borders.
cv::Mat1w holey_frame(unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 2.0);
  cv::Mat1w d(480, 640);
  for (int y = 0; y < d.rows; ++y)
    for (int x = 0; x < d.cols; ++x)
      d(y, x) = static_cast<std::uint16_t>(900 + x / 2 + y + (x > 320 ? 150 : 0) + noise(rng));
  std::uniform_int_distribution<int> px(0, 639), py(0, 479), size(1, 24);
  for (int i = 0; i < 400; ++i) {
    const cv::Rect r = cv::Rect(px(rng), py(rng), size(rng), size(rng)) & cv::Rect(0, 0, 640, 480);
    d(r).setTo(0);
  }
  return d;
}

std::vector<int> indices(const std::vector<proto::EncodedTile>& tiles) {
  std::vector<int> out;
  for (const auto& t : tiles) out.push_back(t.index);
  return out;
}

std::vector<int> mask_indices(const std::vector<bool>& mask, bool value) {
  std::vector<int> out;
  for (std::size_t i = 0; i < mask.size(); ++i)
    if (mask[i] == value) out.push_back(static_cast<int>(i));
  return out;
}

// What a receiver holds after decoding `tiles` over `held`.
void receive(cv::Mat1w& held, const ProcessedFrame& p) {
  for (const auto& t : p.tiles)
    ASSERT_EQ(proto::decode_tile_into(t.bytes, p.grid, t.index, p.codec, held),
              proto::DecodeStatus::Ok);
}

// The message sets process() hands on for one frame sent in parts, in order.
std::vector<ProcessedFrame> parts_of(FramePipeline& p, const DepthFrame& frame,
                                     FrameRequest request,
                                     const std::function<bool()>& preempt = {}) {
  request.frame_parts = true;
  std::vector<ProcessedFrame> parts;
  p.process(
      frame, request, [&](const ProcessedFrame& part) { parts.push_back(part); }, preempt);
  return parts;
}

FrameRequest roi_request(bool key = false) {
  FrameRequest r;
  r.force_key_frame = key;
  r.rois = {{100, 100, 120, 100, 1}, {380, 290, 60, 40, 1}};
  return r;
}

TEST(RoiFirst, RoiPartCarriesExactlyTheRoiTilesThenTheRestCompletesTheFrame) {
  PipelineConfig cfg;  // fill, temporal fill, 80x60 tiles, background every 2nd frame
  cfg.stabilise_k_sigma = 3.0;
  FramePipeline p(cfg);
  const cv::Mat1w d = holey_frame(1);
  const FrameRequest req = roi_request(true);
  const proto::TileGrid grid{640, 480, 80, 60};
  const std::vector<bool> in_roi = tiles_in_rois(grid, req.rois);
  ASSERT_EQ(mask_indices(in_roi, true), (std::vector<int>{9, 10, 17, 18, 25, 26, 36, 37, 44, 45}));

  // Key frame: the ROI part carries every ROI tile and lists them; it is not a key manifest.
  const std::vector<ProcessedFrame> parts1 = parts_of(p, frame_of(d, 1), req);
  ASSERT_EQ(parts1.size(), 2u);
  const ProcessedFrame& roi = parts1[0];
  EXPECT_EQ(roi.part, FramePart::RoiPart);
  EXPECT_TRUE(roi.key_frame);
  EXPECT_FALSE(roi.manifest.key_frame);
  EXPECT_EQ(indices(roi.tiles), mask_indices(in_roi, true));
  EXPECT_EQ(std::vector<int>(roi.manifest.changed_tiles.begin(), roi.manifest.changed_tiles.end()),
            mask_indices(in_roi, true));
  EXPECT_EQ(roi.pixels_processed, 10u * 80u * 60u);

  const ProcessedFrame& rest = parts1[1];
  EXPECT_EQ(rest.part, FramePart::Rest);
  EXPECT_EQ(rest.frame_id, 1u);
  EXPECT_TRUE(rest.manifest.key_frame);
  EXPECT_EQ(indices(rest.tiles), mask_indices(in_roi, false));
  EXPECT_EQ(rest.pixels_processed, 54u * 80u * 60u);

  // A receiver holding both parts holds the sender's frame, and that frame is what a full-frame
  // pipeline produces (the ROI fill's margin makes it exact; first frame, so no history differs).
  cv::Mat1w held(480, 640, std::uint16_t(0));
  receive(held, roi);
  receive(held, rest);
  EXPECT_EQ(cv::norm(held, rest.sent_view_mm, cv::NORM_INF), 0.0);
  FramePipeline reference(cfg);
  const ProcessedFrame whole = reference.process(frame_of(d, 1), {});
  EXPECT_EQ(cv::norm(held, whole.sent_view_mm, cv::NORM_INF), 0.0);
  EXPECT_LT(cv::countNonZero(held == 0), cv::countNonZero(d == 0) / 10);  // it was filled

  // Frame 2 (rest due): the rest's manifest lists the changed tiles of both parts.
  const cv::Mat1w d2 = holey_frame(2);
  const std::vector<ProcessedFrame> parts2 = parts_of(p, frame_of(d2, 2), roi_request());
  ASSERT_EQ(parts2.size(), 2u);
  const ProcessedFrame& roi2 = parts2[0];
  EXPECT_FALSE(roi2.tiles.empty());
  for (int i : indices(roi2.tiles)) EXPECT_TRUE(in_roi[static_cast<std::size_t>(i)]) << i;
  const ProcessedFrame& rest2 = parts2[1];
  EXPECT_FALSE(rest2.manifest.key_frame);
  std::vector<int> both = indices(roi2.tiles);
  for (int i : indices(rest2.tiles)) both.push_back(i);
  std::sort(both.begin(), both.end());
  EXPECT_EQ(
      std::vector<int>(rest2.manifest.changed_tiles.begin(), rest2.manifest.changed_tiles.end()),
      both);
  receive(held, roi2);
  receive(held, rest2);
  EXPECT_EQ(cv::norm(held, rest2.sent_view_mm, cv::NORM_INF), 0.0);

  // Frame 3 (rest not due): one part, ROI tiles only, nothing pending.
  const std::vector<ProcessedFrame> parts3 =
      parts_of(p, frame_of(holey_frame(3), 3), roi_request());
  ASSERT_EQ(parts3.size(), 1u);
  const ProcessedFrame& f3 = parts3[0];
  EXPECT_EQ(f3.part, FramePart::Whole);
  EXPECT_FALSE(f3.manifest.key_frame);
  for (int i : indices(f3.tiles)) EXPECT_TRUE(in_roi[static_cast<std::size_t>(i)]) << i;
  EXPECT_EQ(f3.pixels_processed, 10u * 80u * 60u);
  EXPECT_EQ(f3.tiles.size() + f3.tiles_skipped, 64u);
  receive(held, f3);
  EXPECT_EQ(cv::norm(held, f3.sent_view_mm, cv::NORM_INF), 0.0);
}

TEST(RoiFirst, ACutRestLeavesItsTilesDueAndTheNextFrameCarriesThem) {
  PipelineConfig cfg;
  cfg.background_every = 1000;  // only the cut rest makes frame 2 have a rest
  FramePipeline p(cfg);
  const proto::TileGrid grid{640, 480, 80, 60};
  const std::vector<bool> in_roi = tiles_in_rois(grid, roi_request().rois);
  cv::Mat1w held(480, 640, std::uint16_t(0));

  // Key frame 1; its rest is cut after 5 tiles (a newer frame "arrived").
  int polls = 0;
  const std::vector<ProcessedFrame> parts1 =
      parts_of(p, frame_of(holey_frame(1), 1), roi_request(true), [&] { return ++polls > 5; });
  ASSERT_EQ(parts1.size(), 2u);
  const ProcessedFrame& roi1 = parts1[0];
  const ProcessedFrame& rest1 = parts1[1];
  EXPECT_TRUE(rest1.rest_cut);
  EXPECT_EQ(rest1.tiles.size(), 5u);
  // Cut, so not a key manifest: it lists exactly what both parts carried.
  EXPECT_FALSE(rest1.key_frame);
  EXPECT_FALSE(rest1.manifest.key_frame);
  std::vector<int> carried = indices(roi1.tiles);
  for (int i : indices(rest1.tiles)) carried.push_back(i);
  std::sort(carried.begin(), carried.end());
  EXPECT_EQ(
      std::vector<int>(rest1.manifest.changed_tiles.begin(), rest1.manifest.changed_tiles.end()),
      carried);
  receive(held, roi1);
  receive(held, rest1);
  // What the sender believes the receiver holds is what it holds.
  EXPECT_EQ(cv::norm(held, rest1.sent_view_mm, cv::NORM_INF), 0.0);

  // Frame 2 (background not due by the divider): it is a key frame with a rest, owed by the cut;
  // a second rest in a row is never cut, so it completes whatever `preempt` says.
  const cv::Mat1w d2 = holey_frame(2);
  const std::vector<ProcessedFrame> parts2 =
      parts_of(p, frame_of(d2, 2), roi_request(), [] { return true; });
  ASSERT_EQ(parts2.size(), 2u);
  const ProcessedFrame& roi2 = parts2[0];
  EXPECT_TRUE(roi2.key_frame);
  const ProcessedFrame& rest2 = parts2[1];
  EXPECT_FALSE(rest2.rest_cut);
  EXPECT_TRUE(rest2.manifest.key_frame);
  EXPECT_EQ(indices(rest2.tiles), mask_indices(in_roi, false));
  receive(held, roi2);
  receive(held, rest2);
  EXPECT_EQ(cv::norm(held, rest2.sent_view_mm, cv::NORM_INF), 0.0);

  // Frame 3: nothing owed, background not due: ROI tiles only.
  const std::vector<ProcessedFrame> parts3 =
      parts_of(p, frame_of(holey_frame(3), 3), roi_request());
  ASSERT_EQ(parts3.size(), 1u);
  EXPECT_EQ(parts3[0].part, FramePart::Whole);
  EXPECT_FALSE(parts3[0].key_frame);
}

TEST(RoiFirst, FramesWithoutTheRestDueLeaveNonRoiPixelsAlone) {
  PipelineConfig cfg;
  cfg.hole_fill.max_passes = 0;  // spatial fill off: holes are left to the temporal history
  cfg.temporal.max_age_frames = 4;
  FramePipeline p(cfg);
  const FrameRequest req = roi_request();
  const proto::TileGrid grid{640, 480, 80, 60};
  const std::vector<bool> in_roi = tiles_in_rois(grid, req.rois);
  cv::Mat1b roi_pixels(480, 640, std::uint8_t(0));
  for (int i : mask_indices(in_roi, true)) roi_pixels(grid.rect(i)).setTo(255);
  const auto with_outside = [&](std::uint16_t outside) {
    cv::Mat1w d(480, 640, outside);
    d.setTo(1500, roi_pixels);
    return d;
  };
  // Frame 1: key, everything 1500. Frame 2: rest due, the same.
  EXPECT_EQ(p.process(frame_of(with_outside(1500), 1), req).pixels_processed, 640u * 480u);
  EXPECT_EQ(p.process(frame_of(with_outside(1500), 2), req).pixels_processed, 640u * 480u);
  // Frame 3: rest not due; outside the ROI tiles the camera now sees 2500 mm.
  const ProcessedFrame f3 = p.process(frame_of(with_outside(2500), 3), req);
  EXPECT_EQ(f3.part, FramePart::Whole);
  EXPECT_EQ(f3.pixels_processed, 10u * 80u * 60u);
  EXPECT_EQ(f3.sent_view_mm(0, 0), 1500);
  // Frame 4: rest due, outside is all holes. Had frame 3's outside pixels been recorded, the
  // temporal fill would bring back 2500; untouched, the history still holds frame 2's 1500.
  const ProcessedFrame f4 = p.process(frame_of(with_outside(0), 4), req);
  EXPECT_EQ(f4.pixels_processed, 640u * 480u);
  cv::Mat1w outside_values;
  f4.sent_view_mm.copyTo(outside_values);
  outside_values.setTo(1500, roi_pixels);
  EXPECT_EQ(cv::countNonZero(outside_values != 1500), 0);
}

TEST(RoiFirst, MergedProcessEqualsBothPartsInOneMessageSet) {
  PipelineConfig cfg;
  FramePipeline split(cfg), merged(cfg);
  cv::Mat1w held_split(480, 640, std::uint16_t(0)), held_merged(480, 640, std::uint16_t(0));
  for (std::uint64_t id = 1; id <= 6; ++id) {
    const cv::Mat1w d = holey_frame(static_cast<unsigned>(10 + id));
    const ProcessedFrame m = merged.process(frame_of(d, id), roi_request(id == 1));
    EXPECT_EQ(m.part, FramePart::Whole);
    EXPECT_TRUE(std::is_sorted(m.tiles.begin(), m.tiles.end(),
                               [](const auto& a, const auto& b) { return a.index < b.index; }));
    receive(held_merged, m);
    FrameRequest in_parts = roi_request(id == 1);
    in_parts.frame_parts = true;
    std::size_t tiles = 0;
    proto::FrameManifest closing;
    const ProcessedFrame all =
        split.process(frame_of(d, id), in_parts, [&](const ProcessedFrame& part) {
          receive(held_split, part);
          tiles += part.tiles.size();
          closing = part.manifest;
        });
    EXPECT_EQ(m.tiles.size(), tiles) << id;
    // What process() returns for a frame sent in parts is the same one message set.
    EXPECT_EQ(indices(all.tiles), indices(m.tiles)) << id;
    EXPECT_EQ(all.manifest, m.manifest) << id;
    EXPECT_EQ(all.tiles_skipped, m.tiles_skipped) << id;
    EXPECT_EQ(all.pixels_processed, m.pixels_processed) << id;
    EXPECT_EQ(m.manifest, closing) << id;
    EXPECT_EQ(cv::norm(held_split, held_merged, cv::NORM_INF), 0.0) << id;
    EXPECT_EQ(cv::norm(held_merged, m.sent_view_mm, cv::NORM_INF), 0.0) << id;
  }
}

TEST(RoiFirst, WithoutRoisOrReceiverTheFrameIsWhole) {
  FramePipeline p(PipelineConfig{});
  const cv::Mat1w d = holey_frame(4);
  const std::vector<ProcessedFrame> a = parts_of(p, frame_of(d, 1), {});
  ASSERT_EQ(a.size(), 1u);
  EXPECT_EQ(a[0].part, FramePart::Whole);
  EXPECT_EQ(a[0].tiles.size(), 64u);
  FrameRequest nobody = roi_request();
  nobody.select_tiles = false;
  const std::vector<ProcessedFrame> b = parts_of(p, frame_of(d, 2), nobody);
  ASSERT_EQ(b.size(), 1u);
  EXPECT_EQ(b[0].part, FramePart::Whole);
  EXPECT_TRUE(b[0].tiles.empty());
}

TEST(TileSink, PartsStreamInBatchesAheadOfTheirManifestAndMergedFramesDoNot) {
  PipelineConfig cfg;
  cfg.stream_tiles = 8;
  FramePipeline streaming(cfg), plain(cfg);
  struct Batch {
    std::uint32_t frame_id;
    FramePart part;
    bool key;
    std::vector<int> tiles;
  };
  std::vector<Batch> batches;
  streaming.set_tile_sink([&](const ProcessedFrame& part, std::size_t from) {
    Batch b{part.frame_id, part.part, part.key_frame, {}};
    for (std::size_t i = from; i < part.tiles.size(); ++i) b.tiles.push_back(part.tiles[i].index);
    batches.push_back(std::move(b));
  });
  // A whole key frame (64 tiles): seven batches of 8 stream, the last 8 go with the manifest.
  const cv::Mat1w d = holey_frame(5);
  const ProcessedFrame whole = parts_of(streaming, frame_of(d, 1), {}).at(0);
  const ProcessedFrame reference = plain.process(frame_of(d, 1), {});
  ASSERT_EQ(whole.tiles.size(), 64u);
  EXPECT_EQ(whole.tiles_streamed, 56u);
  ASSERT_EQ(batches.size(), 7u);
  std::vector<int> streamed;
  for (const auto& b : batches) {
    EXPECT_EQ(b.frame_id, 1u);
    EXPECT_EQ(b.part, FramePart::Whole);
    EXPECT_TRUE(b.key);
    EXPECT_EQ(b.tiles.size(), 8u);
    streamed.insert(streamed.end(), b.tiles.begin(), b.tiles.end());
  }
  std::vector<int> first56 = indices(whole.tiles);
  first56.resize(56);
  EXPECT_EQ(streamed, first56);
  // Streaming changes what goes when, not what goes.
  EXPECT_EQ(indices(whole.tiles), indices(reference.tiles));
  for (std::size_t i = 0; i < whole.tiles.size(); ++i)
    EXPECT_EQ(whole.tiles[i].bytes, reference.tiles[i].bytes) << i;
  EXPECT_EQ(whole.manifest, reference.manifest);

  // An ROI part with a rest: the ROI part's batches carry its part and key flags.
  batches.clear();
  const std::vector<ProcessedFrame> parts =
      parts_of(streaming, frame_of(holey_frame(6), 2), roi_request(true));
  ASSERT_EQ(parts.size(), 2u);
  const ProcessedFrame& roi = parts[0];
  const ProcessedFrame& rest = parts[1];
  ASSERT_EQ(roi.part, FramePart::RoiPart);
  const std::size_t roi_batches = roi.tiles_streamed / 8;
  ASSERT_LT(roi_batches, batches.size());
  for (std::size_t i = 0; i < batches.size(); ++i)
    EXPECT_EQ(batches[i].part, i < roi_batches ? FramePart::RoiPart : FramePart::Rest) << i;
  EXPECT_EQ(rest.tiles_streamed, (batches.size() - roi_batches) * 8);
  EXPECT_LT(rest.tiles_streamed, rest.tiles.size());  // the last batch goes with the manifest

  // Without frame_parts, process() merges both parts into one message set in index order:
  // nothing streams, and the next frame sent in parts streams again.
  batches.clear();
  const ProcessedFrame merged = streaming.process(frame_of(holey_frame(7), 3), roi_request(true));
  EXPECT_TRUE(batches.empty());
  EXPECT_EQ(merged.tiles_streamed, 0u);
  parts_of(streaming, frame_of(holey_frame(8), 4), {});
  EXPECT_FALSE(batches.empty());
}

}  // namespace
}  // namespace telex::remote
