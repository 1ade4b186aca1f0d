// SPDX-License-Identifier: MIT
// Stabiliser, tile selection, key frames and ROI rates of the remote pipeline, without a network.
#include "telex/remote/pipeline.h"

#include <gtest/gtest.h>

#include <random>

#include "telex/common/synthetic.h"

namespace telex::remote {
namespace {

DepthFrame frame_of(const cv::Mat1w& depth, std::uint64_t id) {
  DepthFrame f;
  f.image.depth_mm = depth;
  f.image.intrinsics = kinect_v1_intrinsics(depth.cols, depth.rows);
  f.frame_id = id;
  f.capture_ns = static_cast<std::int64_t>(id) * 33'333'333;
  return f;
}

TEST(Stabiliser, ZeroToleranceIsBitExact) {
  Stabiliser s(0.0);
  std::mt19937 rng(3);
  cv::Mat1w in(48, 64), out;
  for (int i = 0; i < 5; ++i) {
    cv::randu(in, 0, 4000);
    s.apply(in, out);
    EXPECT_EQ(cv::norm(in, out, cv::NORM_INF), 0.0);
  }
}

TEST(Stabiliser, HoldsWithinTheNoiseBandAndFollowsRealChanges) {
  Stabiliser s(3.0, /*confirm_frames=*/1);
  // At 1 m the Nguyen sigma is 1.2 + 1.9 * 0.36 = 1.88 mm, so k = 3 gives a 5 mm band.
  EXPECT_EQ(s.tolerance_mm(1000), 5);
  cv::Mat1w a(2, 2, std::uint16_t(1000)), out;
  s.apply(a, out);
  cv::Mat1w b = (cv::Mat1w(2, 2) << 1004, 996, 1006, 0);
  s.apply(b, out);
  EXPECT_EQ(out(0, 0), 1000);  // within 5 mm: held
  EXPECT_EQ(out(0, 1), 1000);
  EXPECT_EQ(out(1, 0), 1006);  // beyond: follows
  EXPECT_EQ(out(1, 1), 0);     // holes pass through
  cv::Mat1w c = (cv::Mat1w(2, 2) << 1000, 1000, 1003, 1000);
  s.apply(c, out);
  EXPECT_EQ(out(1, 0), 1006);  // held around the new value
  EXPECT_EQ(out(1, 1), 1000);  // after a hole the pixel restarts from the measurement
}

TEST(Stabiliser, SmallExcursionsMustPersistLargeJumpsPassAtOnce) {
  Stabiliser s(3.0, /*confirm_frames=*/2,
               /*immediate_factor=*/3.0);  // band 5 mm, jump 15 mm at 1 m
  cv::Mat1w out;
  s.apply(cv::Mat1w(1, 3, std::uint16_t(1000)), out);
  s.apply((cv::Mat1w(1, 3) << 1008, 1008, 1100), out);
  EXPECT_EQ(out(0, 0), 1000);  // one frame outside the band: noise until proven otherwise
  EXPECT_EQ(out(0, 1), 1000);
  EXPECT_EQ(out(0, 2), 1100);  // 100 mm: real motion, no delay
  s.apply((cv::Mat1w(1, 3) << 1001, 1009, 1100), out);
  EXPECT_EQ(out(0, 0), 1000);  // back inside: the excursion is forgotten
  EXPECT_EQ(out(0, 1), 1009);  // second frame outside: taken
  s.apply((cv::Mat1w(1, 3) << 1007, 1009, 1100), out);
  EXPECT_EQ(out(0, 0), 1000);  // a new excursion starts counting from one again
  EXPECT_THROW(Stabiliser(-1.0), std::invalid_argument);
  EXPECT_THROW(Stabiliser(1.0, 0), std::invalid_argument);
}

PipelineConfig no_fill_config() {
  PipelineConfig c;
  c.fill = false;
  c.key_frame_every = 10;
  return c;
}

TEST(FramePipeline, KeyFrameFirstThenOnlyChangedTiles) {
  FramePipeline p(no_fill_config());
  cv::Mat1w d(480, 640, std::uint16_t(1500));
  auto f1 = p.process(frame_of(d, 1), {});
  EXPECT_TRUE(f1.key_frame);
  EXPECT_EQ(f1.tiles.size(), 64u);
  EXPECT_TRUE(f1.manifest.key_frame);
  auto f2 = p.process(frame_of(d, 2), {});
  EXPECT_FALSE(f2.key_frame);
  EXPECT_TRUE(f2.tiles.empty());
  EXPECT_EQ(f2.tiles_skipped, 64u);
  d(130, 170) = 1600;  // tile column 2, row 2 -> index 18
  auto f3 = p.process(frame_of(d, 3), {});
  ASSERT_EQ(f3.tiles.size(), 1u);
  EXPECT_EQ(f3.tiles[0].index, 18);
  EXPECT_EQ(f3.manifest.changed_tiles, std::vector<std::uint16_t>{18});
  EXPECT_EQ(cv::norm(f3.sent_view_mm, d, cv::NORM_INF), 0.0);
  // Each tile decodes alone to the sender's pixels.
  cv::Mat1w tile;
  ASSERT_EQ(proto::decode_depth(f3.tiles[0].bytes, 80, 60, f3.codec, tile),
            proto::DecodeStatus::Ok);
  EXPECT_EQ(cv::norm(tile, d(f3.tiles[0].rect), cv::NORM_INF), 0.0);
}

TEST(FramePipeline, PeriodicAndRequestedKeyFrames) {
  FramePipeline p(no_fill_config());
  cv::Mat1w d(120, 160, std::uint16_t(900));
  std::vector<int> keys;
  for (int i = 1; i <= 25; ++i) {
    FrameRequest r;
    r.force_key_frame = i == 14;
    if (p.process(frame_of(d, static_cast<std::uint64_t>(i)), r).key_frame) keys.push_back(i);
  }
  EXPECT_EQ(keys, (std::vector<int>{1, 11, 14, 24}));
}

TEST(FramePipeline, RoiTilesAtFullRateOthersAtTheBackgroundRate) {
  PipelineConfig c = no_fill_config();
  c.key_frame_every = 1000;
  c.background_every = 3;
  FramePipeline p(c);
  cv::Mat1w d(480, 640, std::uint16_t(1000));
  p.process(frame_of(d, 1), {});
  FrameRequest r;
  r.rois = {proto::RoiRect{0, 0, 80, 60, 1}};  // tile 0 only
  std::vector<std::size_t> sent;
  for (int i = 2; i <= 7; ++i) {
    d += 10;  // every tile changes every frame
    sent.push_back(p.process(frame_of(d, static_cast<std::uint64_t>(i)), r).tiles.size());
  }
  // Frames 3 and 6 are background frames (counter % 3 == 0): all 64 tiles; otherwise the ROI tile.
  EXPECT_EQ(sent, (std::vector<std::size_t>{1, 64, 1, 1, 64, 1}));
}

TEST(FramePipeline, FillClosesSensorHolesOnTheTrueSurface) {
  // "tilted": one plane at 35 deg, so every hole (dropout, grazing) has only that surface around
  // it.
  auto rendered =
      synth::render(synth::Scene::named("tilted"), kinect_v1_intrinsics(), synth::SensorModel{}, 0);
  FramePipeline p(PipelineConfig{});
  auto out = p.process(frame_of(rendered.depth.depth_mm, 1), {});
  ASSERT_GT(out.holes_in, 300u);
  EXPECT_LT(out.holes_out, out.holes_in / 10);
  int near = 0, total = 0;
  for (int y = 0; y < 480; ++y)
    for (int x = 0; x < 640; ++x)
      if (rendered.depth.depth_mm(y, x) == 0 && out.sent_view_mm(y, x) != 0 &&
          rendered.true_depth_m(y, x) > 0) {
        ++total;
        // 3 sigma of the sensor at <= 1.4 m plus one 20 mm fill bin.
        if (std::abs(out.sent_view_mm(y, x) - rendered.true_depth_m(y, x) * 1000.0) < 30.0) ++near;
      }
  ASSERT_GT(total, 300);
  EXPECT_GT(static_cast<double>(near) / total, 0.99);
}

TEST(FramePipeline, FillLeavesFewHolesOnStepEdges) {
  // At the box's step edges the projector shadow is filled from whichever surface dominates the
  // window, so only the count of holes is checked here, not their depth.
  auto rendered =
      synth::render(synth::Scene::named("box"), kinect_v1_intrinsics(), synth::SensorModel{}, 0);
  FramePipeline p(PipelineConfig{});
  auto out = p.process(frame_of(rendered.depth.depth_mm, 1), {});
  EXPECT_GT(out.holes_in, 1000u);
  EXPECT_LT(out.holes_out, out.holes_in / 10);
}

}  // namespace
}  // namespace telex::remote
