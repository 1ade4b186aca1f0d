// SPDX-License-Identifier: MIT
// Surface snapshots: region-of-interest windows, and the pool that recycles snapshot buffers (no
// stale pixels outside the new windows, never a snapshot someone still holds).
#include "telex/local/link/surface_builder.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <deque>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <thread>

#include "telex/base/triple_buffer.h"
#include "telex/common/synthetic.h"

namespace telex::local {
namespace {

AssembledFrame desk_frame(std::uint64_t seed, std::uint32_t id) {
  const Intrinsics k = kinect_v1_intrinsics();
  synth::SensorModel sensor;
  sensor.seed = seed;
  AssembledFrame f;
  f.depth_mm = synth::render(synth::Scene::named("desk"), k, sensor).depth.depth_mm;
  f.intrinsics = k;
  f.frame_id = id;
  return f;
}

const void* buffer(const Surface& s) { return s.depth_m.data; }

SurfaceOptions roi_options() {
  SurfaceOptions o;
  o.roi = true;  // the default since issue 16; spelled out because the tests compare the two
  return o;
}

SurfaceOptions full_options() {
  SurfaceOptions o;
  o.roi = false;
  return o;
}

TEST(SurfaceBuilder, DefaultsAreRadiusSixInFingertipWindows) {
  const SurfaceOptions o;
  EXPECT_TRUE(o.roi);
  EXPECT_TRUE(o.bilateral);
  EXPECT_EQ(o.bilateral_options.radius_px, 6);
  EXPECT_TRUE(o.fill_here) << "the remote sends its depth unfilled";
}

// Pixels (depth or normal) that differ between two snapshots; NaN never occurs in valid ones.
int differing_pixels(const Surface& a, const Surface& b) {
  if (a.depth_m.size() != b.depth_m.size() || a.normals.size() != b.normals.size()) return -1;
  int n = 0;
  for (int v = 0; v < a.depth_m.rows; ++v)
    for (int u = 0; u < a.depth_m.cols; ++u)
      n += a.depth_m(v, u) != b.depth_m(v, u) || a.normals(v, u) != b.normals(v, u);
  return n;
}

// Non-zero depth or normal pixels outside `windows`.
int nonzero_outside(const Surface& s, const std::vector<cv::Rect>& windows) {
  cv::Mat1b outside(s.depth_m.size(), 255);
  for (const auto& r : windows) outside(r).setTo(0);
  int n = 0;
  for (int v = 0; v < s.depth_m.rows; ++v)
    for (int u = 0; u < s.depth_m.cols; ++u) {
      if (!outside(v, u)) continue;
      const cv::Vec3f nv = s.normals(v, u);
      n += s.depth_m(v, u) != 0.0f || nv != cv::Vec3f(0, 0, 0);
    }
  return n;
}

// Station-side fill (issue 16's study): the remote's spatial fill run on the depth as it
// arrived gives, inside the windows, exactly the surface a remote-filled frame gives; over the
// whole frame the same; and it changes nothing when there is no hole.
TEST(SurfaceBuilder, FillHereEqualsTheRemotesSpatialFill) {
  const AssembledFrame raw = desk_frame(1, 1);
  ASSERT_GT(cv::countNonZero(raw.depth_mm == 0), 1000) << "the sensor model leaves holes";
  AssembledFrame filled = raw;
  filled.depth_mm = fill_holes_mode(raw.depth_mm).depth_mm;  // what the remote's fill sends
  const std::vector<cv::Rect> windows{{300, 200, 41, 41}, {100, 50, 33, 33}};
  SurfaceOptions here = roi_options(), trust = roi_options();
  here.fill_here = true;
  trust.fill_here = false;
  SurfaceBuildStats st;
  const auto a = build_surface(raw, here, windows, &st);
  const auto b = build_surface(filled, trust, windows);
  EXPECT_EQ(differing_pixels(*a, *b), 0);
  EXPECT_GT(st.fill_ms, 0.0);
  const auto unfilled = build_surface(raw, trust, windows);
  EXPECT_GT(differing_pixels(*a, *unfilled), 0) << "the fill did something";
  SurfaceOptions here_full = full_options(), trust_full = full_options();
  here_full.fill_here = true;
  trust_full.fill_here = false;
  EXPECT_EQ(
      differing_pixels(*build_surface(raw, here_full, {}), *build_surface(filled, trust_full, {})),
      0);
  // A frame with no hole: the fill changes nothing.
  AssembledFrame solid = filled;
  solid.depth_mm = filled.depth_mm.clone();
  solid.depth_mm.setTo(900, solid.depth_mm == 0);
  EXPECT_EQ(
      differing_pixels(*build_surface(solid, here, windows), *build_surface(solid, trust, windows)),
      0);
}

TEST(SurfaceBuilder, RoiWritesOnlyItsWindowsAndMatchesTheFullFrameThere) {
  const AssembledFrame f = desk_frame(1, 1);
  const std::vector<cv::Rect> windows{{300, 200, 41, 41}, {100, 50, 33, 33}};
  SurfaceBuildStats st;
  const auto roi = build_surface(f, roi_options(), windows, &st);
  const auto full = build_surface(f, full_options(), {});
  EXPECT_EQ(st.pixels_processed, 41u * 41u + 33u * 33u);
  EXPECT_EQ(nonzero_outside(*roi, windows), 0);
  // Inside, away from the window edge (normals there see the margin as holes), the same numbers.
  const cv::Rect inner(304, 204, 33, 33);
  EXPECT_EQ(cv::countNonZero(roi->depth_m(inner) != full->depth_m(inner)), 0);
  EXPECT_GT(cv::countNonZero(roi->depth_m(inner)), 0);
}

TEST(SurfaceBuilder, NoWindowComputesNothing) {
  const AssembledFrame f = desk_frame(1, 1);
  HandState far{};
  far.tips[1].valid = true;
  far.tips[1].p_CameraFingertip = {0.0, 0.0, 0.2};  // far in front of the desk
  const auto windows = fingertip_windows(far, f.depth_mm, f.intrinsics, roi_options());
  EXPECT_TRUE(windows.empty());
  SurfacePool pool(2);
  SurfaceBuildStats st;
  const auto s = build_surface(f, roi_options(), windows, &st, &pool);
  EXPECT_EQ(st.pixels_processed, 0u);
  EXPECT_EQ(nonzero_outside(*s, {}), 0);
}

TEST(SurfaceBuilder, BadWindowIsRefusedAndLeavesThePoolUsable) {
  const AssembledFrame f = desk_frame(1, 1);
  SurfacePool pool(1);
  const std::vector<cv::Rect> outside{{630, 470, 20, 20}};
  EXPECT_THROW(build_surface(f, roi_options(), outside, nullptr, &pool), std::invalid_argument);
  const std::vector<cv::Rect> empty{{10, 10, 0, 5}};
  EXPECT_THROW(build_surface(f, roi_options(), empty, nullptr, &pool), std::invalid_argument);
  const std::vector<cv::Rect> ok{{10, 10, 20, 20}};
  const auto s = build_surface(f, roi_options(), ok, nullptr, &pool);
  EXPECT_EQ(nonzero_outside(*s, ok), 0);
  EXPECT_THROW(SurfacePool(0), std::invalid_argument);
}

TEST(SurfacePool, RecycledRoiSnapshotHoldsNoStaleDataOutsideTheNewWindows) {
  SurfacePool pool(1);
  const AssembledFrame f1 = desk_frame(1, 1), f2 = desk_frame(2, 2);
  const std::vector<cv::Rect> a{{300, 200, 41, 41}, {500, 400, 60, 50}};
  const std::vector<cv::Rect> b{{100, 100, 35, 35}};
  const void* first_buffer = nullptr;
  {
    const auto s1 = build_surface(f1, roi_options(), a, nullptr, &pool);
    first_buffer = buffer(*s1);
    ASSERT_GT(cv::countNonZero(s1->depth_m(a[0])), 0);
  }
  const auto s2 = build_surface(f2, roi_options(), b, nullptr, &pool);
  EXPECT_EQ(pool.recycled(), 1u);
  EXPECT_EQ(pool.allocations(), 1u);
  EXPECT_EQ(buffer(*s2), first_buffer);
  EXPECT_EQ(nonzero_outside(*s2, b), 0);
  EXPECT_EQ(s2->frame_id, 2u);
  // Everything equals a snapshot built without the pool.
  EXPECT_EQ(differing_pixels(*s2, *build_surface(f2, roi_options(), b)), 0);
}

TEST(SurfacePool, RoiAfterFullFrameClearsTheWholeFrame) {
  SurfacePool pool(1);
  const AssembledFrame f = desk_frame(1, 1);
  const void* first_buffer = nullptr;
  {
    const auto full = build_surface(f, full_options(), {}, nullptr, &pool);
    first_buffer = buffer(*full);
    ASSERT_GT(cv::countNonZero(full->depth_m), 250000);
  }
  const std::vector<cv::Rect> w{{200, 150, 40, 40}};
  const auto roi = build_surface(f, roi_options(), w, nullptr, &pool);
  EXPECT_EQ(buffer(*roi), first_buffer);
  EXPECT_EQ(nonzero_outside(*roi, w), 0);
  EXPECT_EQ(differing_pixels(*roi, *build_surface(f, roi_options(), w)), 0);
}

TEST(SurfacePool, WarmFillsThePoolWithZeroedSnapshotsThatAreRecycled) {
  SurfacePool pool(3);
  pool.warm({640, 480});
  EXPECT_EQ(pool.pooled(), 3u);
  EXPECT_EQ(pool.allocations(), 3u);
  pool.warm({640, 480});  // already full: nothing more
  EXPECT_EQ(pool.allocations(), 3u);
  const AssembledFrame f = desk_frame(1, 1);
  const std::vector<cv::Rect> w{{200, 150, 40, 40}};
  const auto s = build_surface(f, roi_options(), w, nullptr, &pool);
  EXPECT_EQ(pool.recycled(), 1u);
  EXPECT_EQ(pool.allocations(), 3u);
  EXPECT_EQ(nonzero_outside(*s, w), 0);
  EXPECT_EQ(differing_pixels(*s, *build_surface(f, roi_options(), w)), 0);
  EXPECT_THROW(pool.warm({0, 480}), std::invalid_argument);
}

TEST(SurfacePool, FullFrameRecycledEqualsFresh) {
  SurfacePool pool(1);
  const AssembledFrame f1 = desk_frame(1, 1), f2 = desk_frame(2, 2);
  { build_surface(f1, full_options(), {}, nullptr, &pool); }
  const auto s = build_surface(f2, full_options(), {}, nullptr, &pool);
  EXPECT_EQ(pool.recycled(), 1u);
  EXPECT_EQ(differing_pixels(*s, *build_surface(f2, full_options(), {})), 0);
}

TEST(SurfacePool, SnapshotStillReferencedIsNeverRecycled) {
  SurfacePool pool(2);
  const AssembledFrame f1 = desk_frame(1, 1), f2 = desk_frame(2, 2);
  const std::vector<cv::Rect> a{{300, 200, 41, 41}};
  const std::vector<cv::Rect> b{{310, 210, 41, 41}};  // overlaps a: reuse would overwrite it
  std::shared_ptr<const Surface> held = build_surface(f1, roi_options(), a, nullptr, &pool);
  const Surface before{held->depth_m.clone(), held->normals.clone(), {}, 0, 1};
  const auto copy = held;  // a second holder, as the triple buffer and the haptic loop are
  held.reset();
  auto s2 = build_surface(f2, roi_options(), b, nullptr, &pool);
  EXPECT_NE(buffer(*s2), buffer(*copy));
  EXPECT_EQ(pool.recycled(), 0u);
  EXPECT_EQ(pool.allocations(), 2u);
  // Pool full and both in use: a third snapshot is allocated outside the pool.
  auto s3 = build_surface(f2, roi_options(), b, nullptr, &pool);
  EXPECT_EQ(pool.allocations(), 3u);
  EXPECT_EQ(pool.pooled(), 2u);
  EXPECT_NE(buffer(*s3), buffer(*copy));
  EXPECT_NE(buffer(*s3), buffer(*s2));
  // s2 released: the next build takes its buffers back, and still leaves `copy` alone.
  const void* second = buffer(*s2);
  s2.reset();
  s3.reset();  // unpooled: simply freed
  const auto s4 = build_surface(f2, roi_options(), b, nullptr, &pool);
  EXPECT_EQ(pool.recycled(), 1u);
  EXPECT_EQ(buffer(*s4), second);
  EXPECT_EQ(copy->frame_id, 1u);
  EXPECT_EQ(differing_pixels(*copy, before), 0);
}

TEST(SurfacePool, NewFrameSizeReplacesTheOldBuffers) {
  SurfacePool pool(2);
  AssembledFrame f = desk_frame(1, 1);
  { build_surface(f, roi_options(), std::vector<cv::Rect>{{0, 0, 20, 20}}, nullptr, &pool); }
  cv::resize(f.depth_mm, f.depth_mm, cv::Size(320, 240), 0, 0, cv::INTER_NEAREST);
  f.intrinsics = f.intrinsics.scaled(320, 240);
  const auto s =
      build_surface(f, roi_options(), std::vector<cv::Rect>{{0, 0, 20, 20}}, nullptr, &pool);
  EXPECT_EQ(s->depth_m.size(), cv::Size(320, 240));
  EXPECT_EQ(pool.recycled(), 0u);
  EXPECT_EQ(pool.pooled(), 1u);
}

// The station's arrangement: the surface thread builds with the pool and keeps a short retire
// ring, the reader takes snapshots through a triple buffer and holds each for a while. Every
// window's depth encodes its frame id; were a held snapshot recycled, the reader would see it
// change under it.
TEST(SurfacePool, ReaderHoldingSnapshotsNeverSeesThemChange) {
  constexpr std::uint32_t kFrames = 3000;
  const Intrinsics k = kinect_v1_intrinsics(160, 120);
  SurfaceOptions o = roi_options();
  o.bilateral = false;
  TripleBuffer<std::shared_ptr<const Surface>> surfaces;
  std::atomic<bool> done{false};
  std::thread writer([&] {
    SurfacePool pool(4);
    std::deque<std::shared_ptr<const Surface>> retired;
    AssembledFrame f;
    f.intrinsics = k;
    for (std::uint32_t i = 1; i <= kFrames; ++i) {
      f.depth_mm = cv::Mat1w(120, 160, static_cast<std::uint16_t>(500 + i % 1000));
      f.frame_id = i;
      const std::vector<cv::Rect> w{{static_cast<int>(i % 100), static_cast<int>(i % 80), 30, 30}};
      std::shared_ptr<const Surface> s = build_surface(f, o, w, nullptr, &pool);
      surfaces.publish(s);
      retired.push_back(s);
      if (retired.size() > 1) retired.pop_front();
    }
    done.store(true);
  });
  std::shared_ptr<const Surface> held;
  std::uint64_t checks = 0, wrong = 0;
  auto expected_m = [](const Surface& s) { return (500 + s.frame_id % 1000) * 1e-3; };
  while (!done.load()) {
    if (!surfaces.take(held) || !held) continue;
    const cv::Rect w(static_cast<int>(held->frame_id % 100), static_cast<int>(held->frame_id % 80),
                     30, 30);
    for (int repeat = 0; repeat < 20; ++repeat) {
      ++checks;
      wrong += std::abs(held->depth_m(w.y + 15, w.x + 15) - expected_m(*held)) > 1e-5;
      wrong += cv::countNonZero(held->depth_m) != 900;
    }
  }
  writer.join();
  EXPECT_GT(checks, 0u);
  EXPECT_EQ(wrong, 0u);
}

}  // namespace
}  // namespace telex::local
