// SPDX-License-Identifier: MIT
// Board spec parsing, the renderer's geometry, and corner detection on rendered boards: corners
// against the truth's projection, and the canonical order under half turns and mirrored lists.
#include "telex/calib/board.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <opencv2/core.hpp>

#include "telex/calib/calibrate.h"
#include "telex/calib/render.h"

namespace telex::calib {
namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;

glm::dmat3 rot_z(double a) {
  const double c = std::cos(a), s = std::sin(a);
  return glm::dmat3(c, s, 0, -s, c, 0, 0, 0, 1);  // columns
}
glm::dmat3 rot_x(double a) {
  const double c = std::cos(a), s = std::sin(a);
  return glm::dmat3(1, 0, 0, 0, c, s, 0, -s, c);
}

// The board's centre on the optical axis at `z_m`, turned in plane by `turn_deg`, tilted about x.
RigidTransform board_facing(const BoardSpec& b, double z_m, double turn_deg, double tilt_deg) {
  const glm::dmat3 R = rot_z(turn_deg * kDeg) * rot_x(tilt_deg * kDeg);
  const glm::dvec3 centre((b.cols - 1) * b.square_m * 0.5, (b.rows - 1) * b.square_m * 0.5, 0.0);
  return {R, glm::dvec3(0.01, -0.005, z_m) - R * centre};
}

// Detected corners against the truth's projection, in board_points order: RMS and max, pixels.
std::pair<double, double> corner_error(const BoardRenderer& r, const BoardSpec& b,
                                       const RigidTransform& X_CameraBoard,
                                       const std::vector<cv::Point2f>& corners) {
  const auto pts = board_points(b);
  double ss = 0.0, worst = 0.0;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const cv::Point2d p = r.project(apply(X_CameraBoard, {pts[i].x, pts[i].y, pts[i].z}));
    const double e = cv::norm(p - cv::Point2d(corners[i]));
    ss += e * e;
    worst = std::max(worst, e);
  }
  return {std::sqrt(ss / static_cast<double>(pts.size())), worst};
}

TEST(BoardSpec, ParsesInnerCornersAndSquare) {
  const BoardSpec b = parse_board("9x6", 30.0);
  EXPECT_EQ(b.cols, 9);
  EXPECT_EQ(b.rows, 6);
  EXPECT_DOUBLE_EQ(b.square_m, 0.030);
  EXPECT_TRUE(b.orientation_unique());
  const BoardSpec c = parse_board("11X8", 24.5);
  EXPECT_EQ(c.cols, 11);
  EXPECT_EQ(c.rows, 8);
  EXPECT_FALSE(parse_board("8x6", 25.0).orientation_unique());
}

TEST(BoardSpec, RejectsBadSpecsNamingTheProblem) {
  struct Case {
    const char* cxr;
    double square_mm;
    const char* says;
  };
  for (const Case& c :
       {Case{"9by6", 30, "is not CxR"}, Case{"9x", 30, "is not CxR"}, Case{"x6", 30, "is not CxR"},
        Case{"9x6x2", 30, "is not CxR"}, Case{"-9x6", 30, "3 to 100"}, Case{"2x6", 30, "3 to 100"},
        Case{"9x101", 30, "3 to 100"}, Case{"7x7", 30, "square board"},
        Case{"9x6", 0, "--square-mm"}, Case{"9x6", -3, "--square-mm"},
        Case{"9x6", 1500, "--square-mm"}, Case{"9x6", NAN, "--square-mm"}}) {
    try {
      parse_board(c.cxr, c.square_mm);
      ADD_FAILURE() << c.cxr << " " << c.square_mm << " was accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(c.says), std::string::npos) << c.cxr << ": " << e.what();
    }
  }
}

TEST(BoardSpec, PointsRowByRowInMetres) {
  const BoardSpec b = parse_board("4x3", 20.0);
  const auto p = board_points(b);
  ASSERT_EQ(p.size(), 12u);
  EXPECT_FLOAT_EQ(p[0].x, 0.0f);
  EXPECT_FLOAT_EQ(p[3].x, 0.06f);
  EXPECT_FLOAT_EQ(p[4].x, 0.0f);
  EXPECT_FLOAT_EQ(p[4].y, 0.02f);
  EXPECT_FLOAT_EQ(p[11].y, 0.04f);
  EXPECT_FLOAT_EQ(p[11].z, 0.0f);
}

TEST(Render, UndistortInvertsTheLensModel) {
  const CameraModel cam = example_render_rig().left;
  const BoardSpec b = parse_board("9x6", 30.0);
  RenderStyle one_sample;
  one_sample.supersample = 1;
  const BoardRenderer r(cam, b, one_sample);
  double worst = 0.0;
  for (double x = -0.6; x <= 0.6; x += 0.1)
    for (double y = -0.45; y <= 0.45; y += 0.09) {
      const cv::Point2d px = r.project({x, y, 1.0});
      const cv::Point2d u = undistort_normalised(
          cam.distortion, {(px.x - cam.k.cx) / cam.k.fx, (px.y - cam.k.cy) / cam.k.fy});
      worst = std::max(worst, std::hypot(u.x - x, u.y - y));
    }
  EXPECT_LT(worst, 1e-10);
}

TEST(Render, CornersFoundWhereTheTruthProjectsThem) {
  const RenderRig rig = example_render_rig();
  const BoardSpec b = parse_board("9x6", 30.0);
  const BoardRenderer eye(rig.right, b, RenderStyle{});
  const BoardRenderer ir(rig.depth, b, ir_style());
  const auto poses = random_board_poses(
      b, {{rig.right, RigidTransform{}}, {rig.depth, inverse(rig.X_RightEyeDepth)}}, 4, 11);
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const RigidTransform X_DepthBoard = compose(inverse(rig.X_RightEyeDepth), poses[i]);
    for (const auto& [name, r, X] :
         {std::tuple{"eye", &eye, poses[i]}, std::tuple{"IR", &ir, X_DepthBoard}}) {
      const CornerDetection d = detect_corners(r->render(X, 100 + i), b);
      ASSERT_TRUE(d.found) << name << " view " << i;
      const auto [rms, worst] = corner_error(*r, b, X, d.corners_px);
      std::printf("[ measured ] %s view %zu: corners %.3f px RMS, %.3f px max from the truth\n",
                  name, i, rms, worst);
      EXPECT_LT(rms, 0.15) << name << " view " << i;
      EXPECT_LT(worst, 0.5) << name << " view " << i;
    }
  }
}

TEST(Render, DepthMapHoldsTheBoardPlane) {
  const RenderRig rig = example_render_rig();
  const BoardSpec b = parse_board("9x6", 30.0);
  const BoardRenderer ir(rig.depth, b, ir_style());
  const RigidTransform X = board_facing(b, 0.6, 0.0, 20.0);
  const cv::Mat1w depth = ir.render_depth(X, 1.6, 0.0, 1);
  const CornerDetection d = detect_corners(ir.render(X, 1), b);
  ASSERT_TRUE(d.found);
  const auto plane = fit_board_plane(depth, rig.depth.k, d.corners_px, b);
  ASSERT_TRUE(plane);
  // Whole-millimetre depth steps only: the fitted plane is the board's to well under a mm.
  EXPECT_LT(plane->fit_rms_mm, 0.5);
  EXPECT_NEAR(plane->offset_m, glm::dot(X.rotation[2], X.translation_m), 3e-4);
  EXPECT_GT(glm::dot(plane->normal_Depth, X.rotation[2]), std::cos(0.1 * kDeg));
  EXPECT_EQ(depth(0, 0), 1600) << "the wall behind";
}

TEST(Detect, HalfTurnedBoardKeepsItsCornerZero) {
  // 9x6: 9 + 6 is odd, so the colours tell a half turn; corner 0 stays the board's corner 0.
  const RenderRig rig = example_render_rig();
  const BoardSpec b = parse_board("9x6", 30.0);
  const BoardRenderer eye(rig.right, b, RenderStyle{});
  for (double turn : {0.0, 90.0, 180.0, 270.0, 160.0}) {
    const RigidTransform X = board_facing(b, 0.55, turn, 15.0);
    const CornerDetection d = detect_corners(eye.render(X, 5), b);
    ASSERT_TRUE(d.found) << turn;
    EXPECT_LT(corner_error(eye, b, X, d.corners_px).second, 0.5) << "turned " << turn << " deg";
  }
}

TEST(Detect, SymmetricBoardOrderedFromTheImageTopLeft) {
  // 8x6: a half turn looks the same, so corner 0 is whichever end is nearer the top left.
  const RenderRig rig = example_render_rig();
  const BoardSpec b = parse_board("8x6", 30.0);
  const BoardRenderer eye(rig.right, b, RenderStyle{});
  for (double turn : {10.0, 190.0}) {
    const CornerDetection d = detect_corners(eye.render(board_facing(b, 0.55, turn, 0.0), 9), b);
    ASSERT_TRUE(d.found) << turn;
    EXPECT_LT(d.corners_px.front().x + d.corners_px.front().y,
              d.corners_px.back().x + d.corners_px.back().y)
        << turn;
  }
}

TEST(Detect, MirroredAndReversedListsComeBackInOrder) {
  const RenderRig rig = example_render_rig();
  const BoardSpec b = parse_board("9x6", 30.0);
  const BoardRenderer eye(rig.right, b, RenderStyle{});
  const cv::Mat img = eye.render(board_facing(b, 0.6, 20.0, -25.0), 3);
  const CornerDetection d = detect_corners(img, b);
  ASSERT_TRUE(d.found);
  auto mirrored = d.corners_px;
  for (int i = 0; i < b.rows; ++i)
    std::reverse(mirrored.begin() + i * b.cols, mirrored.begin() + (i + 1) * b.cols);
  canonical_corner_order(img, b, mirrored);
  EXPECT_EQ(mirrored, d.corners_px);
  auto reversed = d.corners_px;
  std::reverse(reversed.begin(), reversed.end());
  canonical_corner_order(img, b, reversed);
  EXPECT_EQ(reversed, d.corners_px);
  auto flipped_rows = d.corners_px;  // rows in reverse order: a mirror about x
  for (int i = 0; i < b.rows / 2; ++i)
    std::swap_ranges(flipped_rows.begin() + i * b.cols, flipped_rows.begin() + (i + 1) * b.cols,
                     flipped_rows.begin() + (b.rows - 1 - i) * b.cols);
  canonical_corner_order(img, b, flipped_rows);
  EXPECT_EQ(flipped_rows, d.corners_px);
}

TEST(Detect, NoBoardIsNotFoundAndBadImagesThrow) {
  const BoardSpec b = parse_board("9x6", 30.0);
  const cv::Mat grey(480, 640, CV_8UC1, cv::Scalar(110));
  EXPECT_FALSE(detect_corners(grey, b).found);
  EXPECT_THROW(detect_corners(cv::Mat(480, 640, CV_8UC3, cv::Scalar::all(0)), b),
               std::invalid_argument);
  EXPECT_THROW(detect_corners(cv::Mat(), b), std::invalid_argument);
}

}  // namespace
}  // namespace telex::calib
