// SPDX-License-Identifier: MIT
// The depth-image-based warp, headless on Mesa's EGL: a still pose gives the capture back, a turn
// moves the picture by f tan(angle), a box moved sideways in front of a wall opens a hole that is
// shaded neutrally, never stretched from the box's edge, a border the capture did not see takes
// the previous frame, and the ground-truth check (`telex warp --check`) meets its bounds.
#include "telex/local/view/warp.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <glm/gtc/matrix_transform.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "telex/common/hole_fill.h"
#include "telex/common/registration.h"
#include "telex/common/synthetic.h"
#include "telex/local/view/warp_check.h"

namespace telex::local {
namespace {

const cv::Vec3b kRed(0, 0, 230), kBlue(230, 60, 0), kGrey(96, 96, 96), kGreen(0, 200, 0);

// A blue wall at 3 m with a red box face at 1 m over the middle.
struct Scene {
  cv::Mat3b bgr = cv::Mat3b(480, 640, kBlue);
  cv::Mat1w depth_mm = cv::Mat1w(480, 640, std::uint16_t{3000});
  cv::Rect box{260, 180, 120, 120};
  Scene() {
    bgr(box).setTo(kRed);
    depth_mm(box).setTo(1000);
  }
};

bool near(const cv::Vec3b& a, const cv::Vec3b& b, int tol = 2) {
  for (int c = 0; c < 3; ++c)
    if (std::abs(a[c] - b[c]) > tol) return false;
  return true;
}

TEST(Warp, MeshTrianglesDropTheCellsAcrossADepthStepOrAHole) {
  // 64x48 at a step of 8: vertices at x = 0, 8, .., 56, 63 and y = 0, 8, .., 40, 47 (8 x 6 cells).
  cv::Mat1w depth(48, 64, std::uint16_t{1000});
  depth.colRange(32, 64).setTo(3000);  // the cells between x = 24 and 32 cross the step
  std::vector<std::uint32_t> indices;
  mesh_triangles(depth, 8, 0.1, indices);
  EXPECT_EQ(indices.size(), 3u * 2 * (8 - 1) * 6);
  for (std::size_t t = 0; t < indices.size(); t += 3) {
    int lo = 9, hi = -1;
    for (std::size_t c = 0; c < 3; ++c) {
      lo = std::min(lo, static_cast<int>(indices[t + c] % 9));
      hi = std::max(hi, static_cast<int>(indices[t + c] % 9));
    }
    EXPECT_FALSE(lo == 3 && hi == 4) << "a triangle spans the step";
  }
  // A slope of 5 % per cell stays whole; a vertex without depth drops the 6 triangles around it.
  for (int x = 0; x < 64; ++x) depth.col(x).setTo(1000 + 6 * x);
  depth(16, 16) = 0;
  mesh_triangles(depth, 8, 0.1, indices);
  EXPECT_EQ(indices.size(), 3u * (2 * 8 * 6 - 6));
}

TEST(Warp, SmoothBlocksOfCellsMergeAndOnesWithAJumpInsideSplit) {
  // 64x48 at a step of 8 (8 x 6 cells) in blocks of 2 x 2 cells: 4 x 3 blocks, 2 triangles each.
  cv::Mat1w depth(48, 64, std::uint16_t{1000});
  std::vector<std::uint32_t> indices;
  mesh_triangles(depth, 8, 0.1, indices, 2);
  EXPECT_EQ(indices.size(), 3u * 2 * 4 * 3);
  // A nearer spot inside block (1, 1) (pixels 16..32), away from every vertex: the block is drawn
  // as its four cells, whose corners see no jump.
  depth(cv::Rect(20, 20, 3, 3)).setTo(500);
  mesh_triangles(depth, 8, 0.1, indices, 2);
  EXPECT_EQ(indices.size(), 3u * (2 * 11 + 2 * 4));
  // Over the block's middle vertex (pixel 24, 24; vertex 3 * 9 + 3): the six triangles round it
  // drop, the other blocks stay merged.
  depth(cv::Rect(23, 23, 3, 3)).setTo(500);
  mesh_triangles(depth, 8, 0.1, indices, 2);
  EXPECT_EQ(indices.size(), 3u * (2 * 11 + 2 * 4 - 6));
  EXPECT_EQ(std::count(indices.begin(), indices.end(), 30u), 0);
  // A block at the grid's end with too few cells (here 64x40: 5 rows of cells) stays fine.
  mesh_triangles(cv::Mat1w(40, 64, std::uint16_t{1000}), 8, 0.1, indices, 2);
  EXPECT_EQ(indices.size(), 3u * (2 * 4 * 2 + 2 * 8));
}

TEST(Warp, AStillPoseGivesTheCaptureBackWithoutOutlines) {
  const Scene s;
  const Intrinsics k = kinect_v1_intrinsics(640, 480);
  DepthWarp warp(640, 480, {});
  const WarpedEye out = warp.warp(s.bgr, s.depth_mm, k, {});
  ASSERT_EQ(out.bgr.size(), s.bgr.size());
  int differ = 0;
  for (int y = 0; y < 480; ++y)
    for (int x = 0; x < 640; ++x) {
      differ += !near(out.bgr(y, x), s.bgr(y, x), 1);
      ASSERT_NEAR(out.depth_mm(y, x), s.depth_mm(y, x), 2) << x << "," << y;
    }
  // The edge's dropped triangles are filled from the capture's own pixels: no grey outline.
  EXPECT_EQ(differ, 0);
  EXPECT_NE(out.texture, 0u);
}

TEST(Warp, ATurnMovesThePictureByFocalTimesTangent) {
  // A flat wall with a green dot; the head turns 3 degrees to the right (about +y, camera y down):
  // the dot moves left by fx tan(3 deg).
  cv::Mat3b bgr(480, 640, kBlue);
  cv::circle(bgr, {320, 240}, 6, kGreen, cv::FILLED);
  const cv::Mat1w depth(480, 640, std::uint16_t{2000});
  const Intrinsics k = kinect_v1_intrinsics(640, 480);
  const double a = 3.0 * M_PI / 180.0;
  // R_DisplayCapture = R_BaseDisplay^T R_BaseCapture with the display turned by +a about y.
  const glm::dmat3 R_BaseDisplay(glm::rotate(glm::dmat4(1.0), a, glm::dvec3(0, 1, 0)));
  DepthWarp warp(640, 480, {});
  const WarpedEye out = warp.warp(bgr, depth, k, {glm::transpose(R_BaseDisplay), glm::dvec3(0.0)});
  cv::Mat1b green;
  cv::inRange(out.bgr, cv::Scalar(0, 150, 0), cv::Scalar(60, 255, 60), green);
  const cv::Moments m = cv::moments(green, true);
  ASSERT_GT(m.m00, 50.0);
  EXPECT_NEAR(m.m10 / m.m00, 320.0 - k.fx * std::tan(a), 0.5);
  EXPECT_NEAR(m.m01 / m.m00, 240.0, 0.5);
}

// The display 10 cm to the capture's right: the box (1 m) moves 52 px left, the wall (3 m) 17 px,
// uncovering the wall right of the box, which the capture never saw.
TEST(Warp, ADepthDiscontinuityOpensAHoleInsteadOfAStretchedTriangle) {
  const Scene s;
  const Intrinsics k = kinect_v1_intrinsics(640, 480);
  const RigidTransform X_DisplayCapture{glm::dmat3(1.0), glm::dvec3(-0.1, 0.0, 0.0)};
  const double box_shift = k.fx * 0.1 / 1.0, wall_shift = k.fx * 0.1 / 3.0;
  const int hole_x0 = static_cast<int>(std::ceil(s.box.br().x - box_shift)) + 2;
  const int hole_x1 = static_cast<int>(std::floor(s.box.br().x - wall_shift)) - 2;
  ASSERT_GT(hole_x1 - hole_x0, 25);
  DepthWarp warp(640, 480, {.hole_fill = HoleFill::Neutral});
  const WarpedEye out = warp.warp(s.bgr, s.depth_mm, k, X_DisplayCapture);
  for (int y = s.box.y + 4; y < s.box.br().y - 4; ++y)
    for (int x = hole_x0; x < hole_x1; ++x) {
      ASSERT_EQ(out.bgr(y, x), kGrey) << "stretched at " << x << "," << y;
      ASSERT_EQ(out.depth_mm(y, x), 0) << x << "," << y;
    }
  // Either side of the hole the box and the wall are where they belong.
  const int mid = s.box.y + s.box.height / 2;
  EXPECT_TRUE(near(out.bgr(mid, hole_x0 - 6), kRed, 10));
  EXPECT_NEAR(out.depth_mm(mid, hole_x0 - 6), 1000, 3);
  EXPECT_TRUE(near(out.bgr(mid, hole_x1 + 6), kBlue, 10));
  EXPECT_NEAR(out.depth_mm(mid, hole_x1 + 6), 3000, 3);

  // With the previous frame as the fill, the same hole stays neutral: the previous output there
  // (a capture of the wall alone here; in a turn, often the box's old edge) is not what is behind.
  DepthWarp with_previous(640, 480, {.hole_fill = HoleFill::Previous});
  const cv::Mat1w wall_depth(480, 640, std::uint16_t{3000});
  with_previous.warp(cv::Mat3b(480, 640, kBlue), wall_depth, k, {});
  const WarpedEye filled = with_previous.warp(s.bgr, s.depth_mm, k, X_DisplayCapture);
  for (int y = s.box.y + 4; y < s.box.br().y - 4; ++y)
    for (int x = hole_x0; x < hole_x1; ++x) ASSERT_EQ(filled.bgr(y, x), kGrey) << x << "," << y;
}

// The border a capture did not see, which the previous output did (the robot head turned back
// while the operator's stayed): the previous output there with HoleFill::Previous, grey without.
TEST(Warp, TheBorderTheCaptureDidNotSeeShowsThePreviousFrame) {
  const Intrinsics k = kinect_v1_intrinsics(640, 480);
  const cv::Mat1w depth(480, 640, std::uint16_t{2000});
  cv::Mat3b striped(480, 640, kBlue);
  striped.colRange(600, 640).setTo(kGreen);  // the right edge of the previous view
  // The display turned 5 deg right of the base; the previous capture was taken there too, this
  // one at the base: its right border is fx tan(5 deg) = 46 px inside the display's.
  const double a = 5.0 * M_PI / 180.0;
  const glm::dmat3 R_BaseDisplay(glm::rotate(glm::dmat4(1.0), a, glm::dvec3(0, 1, 0)));
  const RigidTransform from_base{glm::transpose(R_BaseDisplay), glm::dvec3(0.0)};
  for (const HoleFill fill : {HoleFill::Previous, HoleFill::Neutral}) {
    DepthWarp warp(640, 480, {.hole_fill = fill});
    warp.warp(striped, depth, k, {});
    const WarpedEye out = warp.warp(cv::Mat3b(480, 640, kBlue), depth, k, from_base);
    EXPECT_TRUE(near(out.bgr(240, 560), kBlue));  // seen by this capture
    for (int x = 600; x < 640; ++x)
      ASSERT_EQ(out.bgr(240, x), fill == HoleFill::Previous ? kGreen : kGrey) << x;
    EXPECT_EQ(out.depth_mm(240, 620), 0);
  }
}

// The room as the remote sends it (the sensor's depth, its holes filled) and as the left eye sees
// it: reprojected 65 mm to the left and its parallax gaps closed, as StereoView::prepare_depth
// does. Warped for a head that turned and rolled a few degrees since the capture, the eye's video
// (one colour here) comes back whole: no neutral seam along the edges the right eye saw past, nor
// along the left border it never saw. Without fill_disocclusions the left eye showed 1-2 px grey
// lines along every occluding edge and a vertical one near its left border.
TEST(Warp, TheLeftEyeWarpsWithoutASeamWhereTheRightEyeSawPastAnEdge) {
  const Intrinsics k = kinect_v1_intrinsics(640, 480);
  const cv::Mat1w right =
      fill_holes_mode(
          synth::render(synth::Scene::named("room"), k, synth::SensorModel{}).depth.depth_mm)
          .depth_mm;
  ASSERT_EQ(cv::countNonZero(right == 0), 0);
  const glm::dvec3 p_RightEye(-0.065, 0.0, 0.0);
  const cv::Mat1w unfilled =
      reproject_depth({right, k}, k, {glm::dmat3(1.0), -p_RightEye}).depth_mm;
  cv::Mat1w left = unfilled.clone();
  const int gaps = cv::countNonZero(left == 0);
  EXPECT_GT(gaps, 1000);  // the parallax opens them
  // Nearly all close; what stays is a few rows of the left border beside the table's edge, where
  // the strip's neighbour is not the surface the strip hides (the warp shows the video there as
  // if far, without a seam).
  EXPECT_GT(fill_disocclusions(left, k.fx, 0.065), static_cast<std::size_t>(gaps * 0.95));
  const glm::dmat3 R_DisplayCapture(glm::rotate(
      glm::rotate(glm::dmat4(1.0), 0.06, glm::dvec3(0, 1, 0)), 0.05, glm::dvec3(0, 0, 1)));
  // Neutral pixels inside the part of the display the capture covers (a turn of 3.4 deg and a
  // roll of 2.9 deg uncover about 35 px at the side and 20 px at the top and bottom).
  const auto seam = [&](const cv::Mat1w& depth, const glm::dvec3& p, double sliver_px) {
    DepthWarp warp(640, 480, {.hole_fill = HoleFill::Neutral, .sliver_px = sliver_px});
    const WarpedEye out = warp.warp(cv::Mat3b(480, 640, kBlue), depth, k,
                                    eye_display_from_capture(R_DisplayCapture, p));
    int n = 0;
    for (int y = 60; y < 420; ++y)
      for (int x = 80; x < 560; ++x) n += out.bgr(y, x) == kGrey;
    return n;
  };
  EXPECT_EQ(seam(right, glm::dvec3(0.0), 2.0), 0) << "right eye";
  EXPECT_EQ(seam(left, p_RightEye, 2.0), 0) << "left eye";
  // What the view drew before: the gaps left open, every sliver neutral.
  const int before = seam(unfilled, p_RightEye, 0.0);
  std::printf("left eye: %d neutral pixels inside the view as before, 0 now\n", before);
  EXPECT_GT(before, 500) << "left eye as before";
}

// fill_disocclusions closes a gap as wide as the parallax opens, with the farther depth, and
// leaves a wider one (the sensor's own hole) open.
TEST(Warp, DisocclusionsTakeTheDepthBehindAndOnlyAsWideAsTheParallax) {
  // fx 500, baseline 0.1 m: an edge from 1 m to 2 m opens 500 * 0.1 * (1 - 0.5) = 25 px.
  cv::Mat1w d(2, 100, std::uint16_t{2000});
  d.row(0).colRange(0, 40).setTo(1000);
  d.row(0).colRange(40, 65).setTo(0);  // 25 px: the parallax's
  d.row(1).colRange(40, 70).setTo(0);  // 30 px between two 2 m depths: the sensor's
  EXPECT_EQ(fill_disocclusions(d, 500.0, 0.1), 25u);
  EXPECT_EQ(d(0, 52), 2000);
  EXPECT_EQ(d(1, 52), 0);
  // At the side: 500 * 0.1 / 2 m = 25 px; a 27 px strip closes with the 2 px slack, 30 px not.
  cv::Mat1w side(2, 100, std::uint16_t{2000});
  side.row(0).colRange(0, 27).setTo(0);
  side.row(1).colRange(0, 30).setTo(0);
  EXPECT_EQ(fill_disocclusions(side, 500.0, -0.1), 27u);
  EXPECT_EQ(side(0, 0), 2000);
  EXPECT_EQ(side(1, 0), 0);
  EXPECT_THROW(fill_disocclusions(side, 0.0, 0.1), std::invalid_argument);
}

TEST(Warp, BadSizesAndOptionsNameThemselves) {
  EXPECT_THROW(DepthWarp(0, 480), std::invalid_argument);
  EXPECT_THROW(DepthWarp(640, 480, {.grid_step_px = 0}), std::invalid_argument);
  EXPECT_THROW(DepthWarp(640, 480, {.merge_cells = 0}), std::invalid_argument);
  EXPECT_THROW(DepthWarp(640, 480, {.sliver_px = -1.0}), std::invalid_argument);
  DepthWarp warp(64, 48, {});
  const Intrinsics k = kinect_v1_intrinsics(64, 48);
  EXPECT_THROW(warp.warp(cv::Mat3b(48, 64), cv::Mat1w(40, 64), k, {}), std::invalid_argument);
}

TEST(WarpCheck, TheWarpHoldsWorldPointsWithinHalfADegreeAtSixtyDegreesPerSecond) {
  WarpCheckOptions o;
  o.width = 640;  // the check's geometry at a smaller size: the bounds are angular
  o.height = 360;
  o.frames = 6;
  const WarpCheckResult r = run_warp_check(o);
  EXPECT_GE(r.points_measured, 20);
  EXPECT_EQ(r.points_missed, 0);
  EXPECT_LE(r.error_deg_with, 0.5);
  // 80 ms at 60 deg/s is 4.8 degrees of turn; the eyes sit off the yaw axis, so a little more.
  EXPECT_GE(r.error_deg_without, 4.0);
  EXPECT_LE(r.error_deg_without, 6.0);
}

// The eye pair and the depth drawn with it captured 20 ms apart while the head yaws at 60 deg/s
// (1.2 degrees between them): warped from the pair's own pose, with the depth brought into it,
// the world holds within the half degree; warped as if the video were captured at the
// depth's pose, the gap's turn shows.
TEST(WarpCheck, APairWarpedFromItsOwnPoseHoldsTheWorldWhereTheDepthsPoseDoesNot) {
  WarpCheckOptions o;
  o.width = 640;
  o.height = 360;
  o.frames = 6;
  o.pair_gap_ms = 20.0;
  const WarpCheckResult r = run_warp_check(o);
  std::printf(
      "pair 20 ms after its depth: error %.3f deg with the pair's pose, %.3f with the "
      "depth's, %.3f without the warp\n",
      r.error_deg_with, r.error_deg_depth_pose, r.error_deg_without);
  EXPECT_GE(r.points_measured, 20);
  EXPECT_EQ(r.points_missed, 0);
  EXPECT_LE(r.error_deg_with, 0.5);
  EXPECT_GE(r.error_deg_depth_pose, 0.9);  // about the 1.2 degrees turned in the gap
  EXPECT_GE(r.error_deg_depth_pose, r.error_deg_with + 0.6);
}

}  // namespace
}  // namespace telex::local
