// SPDX-License-Identifier: MIT
// The region-by-region forms of the fill stages used by the remote's ROI-first pipeline: they must
// equal the full-frame forms where they run and leave everything else alone.
#include <gtest/gtest.h>

#include <random>

#include "telex/common/depth_image.h"
#include "telex/common/hole_fill.h"
#include "telex/common/synthetic.h"
#include "telex/common/temporal_fill.h"

namespace telex {
namespace {

TEST(HoleFillRoiInto, EqualsFullFrameInsideAndTouchesNothingOutside) {
  const auto r =
      synth::render(synth::Scene::named("box"), kinect_v1_intrinsics(), synth::SensorModel{}, 1);
  cv::Mat1w d = r.depth.depth_mm.clone();
  d(cv::Rect(250, 200, 40, 30)).setTo(0);  // a gap needing several passes
  d(cv::Rect(75, 50, 12, 80)).setTo(0);    // one across a tile border
  for (const HoleFillOptions o :
       {HoleFillOptions{}, HoleFillOptions{3, 20, 4, 1}, HoleFillOptions{7, 10, 16, 2}}) {
    const auto full = fill_holes_mode(d, o);
    for (const cv::Rect roi :
         {cv::Rect(240, 180, 80, 60), cv::Rect(0, 0, 640, 480), cv::Rect(560, 420, 80, 60),
          cv::Rect(80, 60, 80, 60), cv::Rect(260, 205, 10, 10)}) {
      cv::Mat1w out(d.size(), std::uint16_t(7));  // sentinel: must survive outside the ROI
      const auto part = fill_holes_mode_roi_into(d, roi, out, o);
      EXPECT_TRUE(part.depth_mm.empty());
      EXPECT_EQ(cv::norm(out(roi), full.depth_mm(roi), cv::NORM_INF), 0.0) << roi;
      cv::Mat1w outside = out.clone();
      outside(roi).setTo(7);
      EXPECT_EQ(cv::countNonZero(outside != 7), 0) << roi;
      EXPECT_EQ(part.holes_in, count_holes(d(roi)));
      EXPECT_EQ(part.holes_out, count_holes(out(roi)));
    }
  }
  cv::Mat1w out;
  EXPECT_THROW(fill_holes_mode_roi_into(d, cv::Rect(600, 0, 80, 60), out), std::invalid_argument);
  EXPECT_THROW(fill_holes_mode_roi_into(d, cv::Rect(0, 0, 0, 60), out), std::invalid_argument);
}

TEST(TemporalFillRect, TileByTileEqualsWholeFrameAndUnvisitedPixelsKeepTheirHistory) {
  TemporalFill whole, tiled;
  std::mt19937 rng(9);
  cv::Mat1w out_whole, out_tiled(48, 64);
  for (int f = 0; f < 8; ++f) {
    cv::Mat1w in(48, 64);
    cv::randu(in, 500, 4000);
    cv::Mat1b holes(48, 64);
    cv::randu(holes, 0, 3);
    in.setTo(0, holes == 0);
    const double t = 33.3 * f;
    const auto rw = whole.apply(in, t, out_whole);
    EXPECT_EQ(tiled.begin_frame(in.size(), t), rw.history_reset);
    std::size_t filled = 0;
    for (int y = 0; y < 48; y += 16)
      for (int x = 0; x < 64; x += 16)
        filled += tiled.apply_rect(in, cv::Rect(x, y, 16, 16), out_tiled).filled;
    EXPECT_EQ(filled, rw.filled);
    EXPECT_EQ(cv::norm(out_whole, out_tiled, cv::NORM_INF), 0.0) << f;
  }
  // A pixel not visited for a frame keeps its history, one frame older.
  TemporalFill t(TemporalFillOptions{2, 0.0});
  cv::Mat1w out(1, 2);
  t.begin_frame({2, 1}, 0);
  t.apply_rect(cv::Mat1w(1, 2, std::uint16_t(1000)), {0, 0, 2, 1}, out);
  t.begin_frame({2, 1}, 33);
  t.apply_rect(cv::Mat1w(1, 2, std::uint16_t(3000)), {0, 0, 1, 1}, out);  // pixel 1 unvisited
  t.begin_frame({2, 1}, 66);
  t.apply_rect(cv::Mat1w(1, 2, std::uint16_t(0)), {0, 0, 2, 1}, out);
  EXPECT_EQ(out(0, 0), 3000);
  EXPECT_EQ(out(0, 1), 1000);  // two frames old: still young enough
  t.begin_frame({2, 1}, 99);
  t.apply_rect(cv::Mat1w(1, 2, std::uint16_t(0)), {0, 0, 2, 1}, out);
  EXPECT_EQ(out(0, 1), 0);  // three frames: aged out
  cv::Mat1w wrong;
  EXPECT_DEATH(t.apply_rect(cv::Mat1w(1, 2, std::uint16_t(0)), {0, 0, 2, 1}, wrong),
               "TELEX_DEMAND");
  EXPECT_DEATH(t.apply_rect(cv::Mat1w(1, 2, std::uint16_t(0)), {1, 0, 2, 1}, out), "TELEX_DEMAND");
}

}  // namespace
}  // namespace telex
