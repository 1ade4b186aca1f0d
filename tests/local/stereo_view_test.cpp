// SPDX-License-Identifier: MIT
// The operator's stereo view: the tracked arm and hand appear in both eyes with the right
// disparity, a fingertip in contact shows its pressure colour, one eye's video serves both with a
// flag, and the status text fits the image.
#include "telex/local/view/stereo_view.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <opencv2/imgproc.hpp>

#include "stereo_view_fixtures.h"
#include "telex/local/view/openxr_output.h"

namespace telex::local {
namespace {

using test::count;
using test::green_dot_ahead;
using test::green_x;
using test::reaching_hand;

TEST(StereoView, TheTrackedArmAndHandAppearInBothEyesShiftedByTheDisparity) {
  StereoView view(640, 480);
  StereoViewInputs in;
  in.k = kinect_v1_intrinsics(640, 480);
  in.hand = reaching_hand();
  const cv::Vec3b grey(60, 60, 60);
  in.eye_bgr = {cv::Mat3b(480, 640, grey), cv::Mat3b(480, 640, grey)};
  const StereoViewImages v = view.render(in);
  ASSERT_EQ(v.sbs.size(), cv::Size(1280, 480));
  EXPECT_FALSE(v.one_eye);
  // Skin-shaded pixels (red channel above blue) in both eyes: the forearm and the hand.
  const auto skin = [](const cv::Vec3b& c) { return c[2] > c[0] + 30; };
  const int right_px = count(v.right, skin), left_px = count(v.left, skin);
  EXPECT_GT(right_px, 2000);
  EXPECT_GT(left_px, 2000);
  // The index fingertip (0.03, 0.10, 0.555): the left eye sees it f*B/Z to the right.
  const glm::dvec3 tip = in.hand.joints_camera[1][3];
  const double u = in.k.fx * tip.x / tip.z + in.k.cx, vv = in.k.fy * tip.y / tip.z + in.k.cy;
  const double d = in.k.fx * in.baseline_m / tip.z;
  EXPECT_TRUE(skin(v.right(static_cast<int>(vv), static_cast<int>(u))));
  EXPECT_TRUE(skin(v.left(static_cast<int>(vv), static_cast<int>(u + d))));
}

// --view-overlays (issue 50): the status band is drawn into each eye only when asked; without it
// the eyes are the scene alone (off by default for --view hmd).
TEST(StereoView, TheStatusBandIsDrawnOnlyWhenTheOverlaysAreOn) {
  StereoView view(320, 240);
  StereoViewInputs in;
  in.k = kinect_v1_intrinsics(320, 240);
  in.hand = reaching_hand();
  const cv::Vec3b grey(60, 60, 60);
  in.eye_bgr = {cv::Mat3b(240, 320, grey), cv::Mat3b(240, 320, grey)};
  in.status = "surface 30.0 fps | latency 5.0 ms | streaming";
  const StereoViewImages on = view.render(in);
  in.overlays = false;
  const StereoViewImages off = view.render(in);
  cv::Mat diff;
  cv::absdiff(on.right, off.right, diff);
  cv::Mat1b changed;
  cv::cvtColor(diff, changed, cv::COLOR_BGR2GRAY);
  const int n = cv::countNonZero(changed > 0);
  EXPECT_GT(n, 200) << "the overlays changed " << n << " pixels";
  // The band darkens the bottom of each eye to a third; without overlays the video is as it came.
  const cv::Rect bottom(0, 232, 320, 8);
  const double with = cv::mean(on.right(bottom))[1], without = cv::mean(off.right(bottom))[1];
  EXPECT_LT(with, 0.5 * without) << with << " against " << without;
}

TEST(StereoView, AFingertipInContactShowsItsPressureAndOneEyeServesBoth) {
  StereoView view(640, 480);
  StereoViewInputs in;
  in.k = kinect_v1_intrinsics(640, 480);
  in.hand = reaching_hand();
  in.forces[1].contact = true;
  in.forces[1].normal_force_N = 3.0;  // red
  in.forces[1].force_N = {0.0, 0.0, -3.0};
  in.forces[1].p_ModelProxy = in.hand.joints_camera[1][3];
  in.eye_bgr[1] = cv::Mat3b(480, 640, cv::Vec3b(60, 60, 60));  // right eye only
  in.status = std::string(300, 'x');  // far wider than the image: shrunk to fit
  const StereoViewImages v = view.render(in);
  EXPECT_TRUE(v.one_eye);
  const auto red = [](const cv::Vec3b& c) { return c[2] > 150 && c[1] < 60 && c[0] < 60; };
  EXPECT_GT(count(v.right, red), 30);
  EXPECT_GT(count(v.left, red), 30);
  // The status band spans the bottom rows and the text stays inside the image.
  EXPECT_LT(v.right(470, 635)[0], 60);
}

TEST(StereoView, EachEyeIsPairedWithTheVideoFrameCapturedNearestToTheDepth) {
  const std::vector<std::int64_t> captures{100, 133, 166, 200};
  EXPECT_EQ(nearest_capture(captures, 150), 2u);  // 166 is 16 away, 133 is 17
  EXPECT_EQ(nearest_capture(captures, 0), 0u);
  EXPECT_EQ(nearest_capture(captures, 1000), 3u);
  EXPECT_EQ(nearest_capture(captures, 133), 1u);
  const std::vector<std::int64_t> tie{10, 20};
  EXPECT_EQ(nearest_capture(tie, 15), 0u);  // the first of equals
  EXPECT_FALSE(nearest_capture({}, 5).has_value());
}

// With both head poses the eyes' video is reprojected to the operator's: a dot straight ahead of
// the robot head at capture appears fx tan(a) to the left once the operator has turned a to the
// right, in both eyes; without them (or --warp off) it stays where the camera saw it.
TEST(StereoView, WithBothHeadPosesTheVideoIsWarpedToTheOperatorsHead) {
  StereoView view(640, 480);
  StereoViewInputs in = green_dot_ahead();
  const StereoViewImages still = view.render(in);
  EXPECT_FALSE(still.warped);
  EXPECT_NEAR(green_x(still.right), 320.0, 0.5);

  const double a = 4.0 * 3.14159265358979323846 / 180.0;
  in.R_BaseDepth = glm::dmat3(1.0);
  in.R_BaseDisplay = glm::dmat3(glm::dvec3(std::cos(a), 0.0, -std::sin(a)), glm::dvec3(0, 1, 0),
                                glm::dvec3(std::sin(a), 0.0, std::cos(a)));
  const StereoViewImages turned = view.render(in);
  EXPECT_TRUE(turned.warped);
  EXPECT_NEAR(green_x(turned.right), 320.0 - in.k.fx * std::tan(a), 1.0);
  // The left eye sits off the turn's axis (the right eye): at 3 m its shift is the same but for
  // the parallax of a 4.5 mm step, under 1 px.
  EXPECT_NEAR(green_x(turned.left), 320.0 - in.k.fx * std::tan(a), 1.5);
}

// The eye pair captured at its own head pose (1 degree further right than the depth's, 16 ms at
// 60 deg/s): the dot straight ahead of the video's camera is where the world puts it at the
// operator's pose, fx tan(b - a) from the centre; taken as captured at the depth's pose (a pair
// without a pose) it is fx tan(b) off that.
TEST(StereoView, ThePairsOwnHeadPoseTurnsTheVideoAndTheDepthIsBroughtToIt) {
  StereoView view(640, 480);
  StereoViewInputs in = green_dot_ahead();
  // A wall 3 m away across the depth's view, but for a near box on the left: the depth has its
  // own pose, and where the video takes its colours follows the wall, not the box.
  in.depth_mm(cv::Rect(0, 0, 120, 480)).setTo(1000);
  const auto yaw = [](double rad) {
    return glm::dmat3(glm::dvec3(std::cos(rad), 0.0, -std::sin(rad)), glm::dvec3(0, 1, 0),
                      glm::dvec3(std::sin(rad), 0.0, std::cos(rad)));
  };
  const double deg = 3.14159265358979323846 / 180.0;
  const double a = 4.0 * deg, b = 1.0 * deg;
  in.R_BaseDepth = glm::dmat3(1.0);
  in.R_BaseDisplay = yaw(a);
  in.R_BaseVideo = yaw(b);
  const StereoViewImages own = view.render(in);
  ASSERT_TRUE(own.warped);
  EXPECT_NEAR(green_x(own.right), 320.0 + in.k.fx * std::tan(b - a), 1.0);
  EXPECT_NEAR(green_x(own.left), 320.0 + in.k.fx * std::tan(b - a), 1.5);
  in.R_BaseVideo.reset();
  const StereoViewImages depth_pose = view.render(in);
  EXPECT_NEAR(green_x(depth_pose.right), 320.0 - in.k.fx * std::tan(a), 1.0);
  EXPECT_GT(green_x(own.right) - green_x(depth_pose.right), 8.0);
}

TEST(StereoView, EyesComeOutAtTheRequestedSizeElseTheVideosElseTheDepths) {
  StereoView view(640, 480);
  StereoViewInputs in;
  in.k = kinect_v1_intrinsics(640, 480);
  in.hand = reaching_hand();
  in.depth_mm = cv::Mat1w(480, 640, std::uint16_t{2000});
  in.eye_size = {1280, 720};
  in.eye_bgr = {cv::Mat3b(480, 640, cv::Vec3b(60, 60, 60)),
                cv::Mat3b(480, 640, cv::Vec3b(60, 60, 60))};
  StereoViewImages v = view.render(in);
  EXPECT_EQ(v.left.size(), cv::Size(1280, 720));
  EXPECT_EQ(v.right.size(), cv::Size(1280, 720));
  EXPECT_EQ(v.sbs.size(), cv::Size(2560, 720));
  in.eye_size = {};
  in.eye_bgr = {cv::Mat3b(720, 1280, cv::Vec3b(60, 60, 60)), cv::Mat3b()};
  EXPECT_EQ(view.render(in).right.size(), cv::Size(1280, 720));
  in.eye_bgr = {};
  EXPECT_EQ(view.render(in).right.size(), cv::Size(640, 480));
}

// A wall 30 cm away fills the depth's rows above `edge_row` (640x480); the rest is far. The
// 1280x720 eyes see the depth camera at twice its scale with 120 rows cropped top and bottom, so
// the wall must end at the eye row that sees depth row `edge_row`, not at a stretched one.
TEST(StereoView, TheRemoteDepthHidesTheBodyWhereItsRaysMeetItAtTheEyesSize) {
  StereoView view(1280, 720);
  StereoViewInputs in;
  in.k = kinect_v1_intrinsics(640, 480);
  in.hand = reaching_hand();
  in.eye_size = {1280, 720};
  const glm::dvec3 tip = in.hand.joints_camera[1][3];
  const double tip_row_depth = in.k.fy * tip.y / tip.z + in.k.cy;
  const Intrinsics k_eye = eye_intrinsics(in.k, in.eye_size);
  EXPECT_DOUBLE_EQ(k_eye.fx, 2.0 * in.k.fx);
  EXPECT_DOUBLE_EQ(k_eye.cy, (in.k.cy + 0.5) * 2.0 - 0.5 - 120.0);
  const int u = static_cast<int>(std::lround(k_eye.fx * tip.x / tip.z + k_eye.cx));
  const int v = static_cast<int>(std::lround(k_eye.fy * tip.y / tip.z + k_eye.cy));
  const auto skin = [](const cv::Vec3b& c) { return c[2] > c[0] + 30; };
  const auto right_at_tip = [&](int edge_row) {
    in.depth_mm = cv::Mat1w(480, 640, std::uint16_t{3000});
    in.depth_mm(cv::Rect(0, 0, 640, edge_row)).setTo(300);
    return view.render(in).right(v, u);
  };
  const int row = static_cast<int>(tip_row_depth);
  EXPECT_FALSE(skin(right_at_tip(row + 3))) << "the wall reaches 3 depth rows below the tip";
  EXPECT_TRUE(skin(right_at_tip(row - 3))) << "the wall ends 3 depth rows above the tip";
}

// A hand half behind a wall: its upper rows hide the fingertips, with a grey video that has
// structure (the skin's exposure and the composite both read it).
StereoViewInputs hand_at_a_wall() {
  StereoViewInputs in;
  in.k = kinect_v1_intrinsics(640, 480);
  in.hand = reaching_hand();
  in.depth_mm = cv::Mat1w(480, 640, std::uint16_t{3000});
  in.depth_mm(cv::Rect(0, 0, 640, 300)).setTo(500);
  cv::Mat3b eye(480, 640, cv::Vec3b(60, 60, 60));
  cv::rectangle(eye, cv::Rect(100, 50, 200, 120), cv::Scalar(150, 140, 30), cv::FILLED);
  in.eye_bgr = {eye, eye.clone()};
  return in;
}

// The work that depends on the depth frame alone (each eye's depth, the normal-map inset) is done
// once per frame and reused while the display draws faster than the depth comes; a new frame is
// drawn anew, exactly as a view that never saw the old one draws it.
TEST(StereoView, TheDepthsWorkIsReusedForItsFrameAndRedoneForANewOne) {
  const StereoViewInputs in = hand_at_a_wall();
  StereoView view(640, 480);
  const StereoViewImages a = view.render(in);
  const StereoViewImages again = view.render(in);
  EXPECT_EQ(cv::norm(a.sbs, again.sbs, cv::NORM_INF), 0.0);
  StereoViewInputs nearer = in;  // a new depth frame: a wall 20 cm away hides the whole body
  nearer.depth_mm = cv::Mat1w(480, 640, std::uint16_t{200});
  const StereoViewImages b = view.render(nearer);
  StereoView fresh(640, 480);
  EXPECT_EQ(cv::norm(fresh.render(nearer).sbs, b.sbs, cv::NORM_INF), 0.0);
  // Without the inset (its normals' colours count as skin): the body is hidden by the new wall.
  const auto skin = [](const cv::Vec3b& c) { return c[2] > c[0] + 30; };
  StereoViewInputs bare = in;
  bare.overlays = nearer.overlays = false;
  EXPECT_GT(count(view.render(bare).right, skin), 2000);
  const StereoViewImages hidden = view.render(nearer);
  EXPECT_LT(count(hidden.right, skin), 50) << "the old frame's depth was drawn";
  EXPECT_LT(count(hidden.left, skin), 50);
}

TEST(StereoView, ALateVideoThatChangesNothingGivesTheSameImagesAsTheOneShot) {
  const StereoViewInputs in = hand_at_a_wall();
  StereoView one_shot(640, 480), latched(640, 480);
  const StereoViewImages a = one_shot.render(in);
  int calls = 0;
  const StereoViewImages b = latched.render(in, [&](StereoViewInputs&) { ++calls; });
  EXPECT_EQ(calls, 1);
  ASSERT_EQ(a.sbs.size(), b.sbs.size());
  EXPECT_EQ(cv::norm(a.sbs, b.sbs, cv::NORM_INF), 0.0);
  const auto skin = [](const cv::Vec3b& c) { return c[2] > c[0] + 30; };
  EXPECT_GT(count(b.right, skin), 1000) << "the body is drawn";
}

TEST(StereoView, TheLateVideoIsShownUnderTheBodyDrawnBeforeIt) {
  const StereoViewInputs in = hand_at_a_wall();
  StereoView view(640, 480);
  const cv::Vec3b blue(250, 120, 120);
  const StereoViewImages v = view.render(in, [&](StereoViewInputs& late) {
    late.eye_bgr = {cv::Mat3b(480, 640, blue), cv::Mat3b(480, 640, blue)};
    late.status = "late";
  });
  // Away from the body and the contact shadows the eyes show the late video, not the early one.
  for (const cv::Mat3b* eye : {&v.left, &v.right}) {
    EXPECT_EQ((*eye)(100, 200), blue) << "where the early video had its teal rectangle";
    EXPECT_EQ((*eye)(400, 40), blue);
  }
  // The body is over it, still hidden by the wall: the same skin pixels as a one-shot render of
  // the early inputs (the skin lit by the early video, as drawn before the late one came).
  StereoView one_shot(640, 480);
  const StereoViewImages early = one_shot.render(in);
  const auto skin = [](const cv::Vec3b& c) { return c[2] > c[0] + 30; };
  int same = 0, skin_px = 0;
  for (int y = 0; y < 470; ++y)
    for (int x = 0; x < 640; ++x) {
      if (!skin(early.right(y, x))) continue;
      ++skin_px;
      same += early.right(y, x) == v.right(y, x);
    }
  EXPECT_GT(skin_px, 1000);
  EXPECT_GT(same, skin_px * 9 / 10);
}

}  // namespace
}  // namespace telex::local
