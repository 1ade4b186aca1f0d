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

#include "telex/local/view/openxr_output.h"

namespace telex::local {
namespace {

// A right hand reaching forward, 45 cm in front of the eyes, fingers along +z.
HandState reaching_hand() {
  HandState h;
  h.time_ns = 1;
  h.skeleton_valid = true;
  h.wrist_camera = {0.05, 0.10, 0.40};
  for (std::size_t f = 0; f < kFingerCount; ++f) {
    const double x = 0.05 + (static_cast<double>(f) - 2.0) * 0.02;
    for (std::size_t j = 0; j < 4; ++j)
      h.joints_camera[f][j] = {x, 0.10, 0.48 + 0.025 * static_cast<double>(j)};
    h.tips[f].valid = true;
    h.tips[f].finger = static_cast<int>(f);
    h.tips[f].p_CameraFingertip = h.joints_camera[f][3];
  }
  return h;
}

int count(const cv::Mat3b& img, const std::function<bool(const cv::Vec3b&)>& pred) {
  int n = 0;
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) n += pred(img(y, x));
  return n;
}

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

// Both eyes see a green dot straight ahead of the camera on grey, over a wall 3 m away.
StereoViewInputs green_dot_ahead() {
  StereoViewInputs in;
  in.k = kinect_v1_intrinsics(640, 480);
  cv::Mat3b eye(480, 640, cv::Vec3b(60, 60, 60));
  cv::rectangle(eye, cv::Rect(314, 234, 13, 13), cv::Vec3b(0, 220, 0), cv::FILLED);
  in.eye_bgr = {eye, eye};
  in.depth_mm = cv::Mat1w(480, 640, std::uint16_t{3000});
  return in;
}

// The green dot's mean column in an eye image, -1 when hardly any of it shows.
double green_x(const cv::Mat3b& img) {
  double sum = 0.0;
  int n = 0;
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x)
      if (img(y, x)[1] > 150 && img(y, x)[0] < 80 && img(y, x)[2] < 80) {
        sum += x;
        ++n;
      }
  return n > 50 ? sum / n : -1.0;
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

namespace telex::local {
namespace {

// Where OpenXR's projection with `fov` puts a point of the eye's frame (x right, y down, z
// forward) in a width x height image, pixel centres at integers, top row 0: the compositor's
// convention, computed from the tangents alone (not through pinhole_from_fov).
cv::Point2d pixel_from_fov(const XrEyeFov& fov, int width, int height, const glm::dvec3& p) {
  const double tan_right = p.x / p.z, tan_up = -p.y / p.z;
  const double l = std::tan(fov.angle_left_rad), r = std::tan(fov.angle_right_rad);
  const double u = std::tan(fov.angle_up_rad), d = std::tan(fov.angle_down_rad);
  return {width * (tan_right - l) / (r - l) - 0.5, height * (u - tan_up) / (u - d) - 0.5};
}

// The centroid of the pixels `pick` takes, within `window` of `near`.
cv::Point2d centroid(const cv::Mat3b& img, const std::function<bool(const cv::Vec3b&)>& pick,
                     cv::Point2d near, int window) {
  double su = 0, sv = 0, n = 0;
  for (int v = std::max(0, static_cast<int>(near.y) - window);
       v < std::min(img.rows, static_cast<int>(near.y) + window); ++v)
    for (int u = std::max(0, static_cast<int>(near.x) - window);
         u < std::min(img.cols, static_cast<int>(near.x) + window); ++u)
      if (pick(img(v, u))) {
        su += u;
        sv += v;
        ++n;
      }
  return n > 0 ? cv::Point2d(su / n, sv / n) : cv::Point2d(-1e9, -1e9);
}

// The project's runtime's canted pair of fields of view (tools/sim/openxr/runtime.cpp eye_fovs),
// wider than the eye camera, for kW x kH eyes.
const std::array<XrEyeFov, 2> kSimRuntimeFov{XrEyeFov{-0.87, 0.75, 0.82, -0.87},
                                             XrEyeFov{-0.75, 0.87, 0.82, -0.87}};
constexpr int kW = 640, kH = 720;
// The eye video: green, a white dot at camera pixel dot_px (470, 130), as both eyes'
// (uncalibrated: each seen through the depth camera's pinhole from its own centre), drawn with a
// reaching hand in kSimRuntimeFov.
const cv::Point2d dot_px(470.0, 130.0);
StereoViewInputs dot_video_in_fov() {
  StereoViewInputs in;
  in.k = kinect_v1_intrinsics(640, 480);
  in.hand = reaching_hand();
  cv::Mat3b video(480, 640, cv::Vec3b(40, 150, 40));
  cv::rectangle(video, cv::Rect(468, 128, 5, 5), cv::Scalar(255, 255, 255), cv::FILLED);
  in.eye_bgr = {video, video};
  for (std::size_t eye = 0; eye < 2; ++eye)
    in.display_k[eye] = pinhole_from_fov(kSimRuntimeFov[eye], kW, kH);
  return in;
}

// --view openxr draws each eye in the field of view the runtime located for it: here the project's
// runtime's canted pair (tools/sim/openxr/runtime.cpp eye_fovs), wider than the eye camera. A
// point of the eye video and the index fingertip of the drawn hand land where that fov (the one
// submitted) puts them; beyond the camera's field the eye is neutral, not the video stretched.
TEST(OpenXrEyeFov, AKnownPointLandsWhereTheSubmittedFovPutsIt) {
  const std::array<XrEyeFov, 2>& fov = kSimRuntimeFov;
  StereoView view(kW, kH);
  StereoViewInputs in = dot_video_in_fov();
  const StereoViewImages v = view.render(in);
  ASSERT_EQ(v.right.size(), cv::Size(kW, kH));
  ASSERT_EQ(v.left.size(), cv::Size(kW, kH));

  const glm::dvec3 ray_dot{(dot_px.x - in.k.cx) / in.k.fx, (dot_px.y - in.k.cy) / in.k.fy, 1.0};
  const auto white = [](const cv::Vec3b& c) { return c[0] > 200 && c[1] > 200 && c[2] > 200; };
  const auto skin = [](const cv::Vec3b& c) { return c[2] > c[0] + 30; };
  const glm::dvec3 tip_right = in.hand.joints_camera[1][3];
  for (const Side side : kSides) {
    SCOPED_TRACE(side == Side::Left ? "left eye" : "right eye");
    const cv::Mat3b& img = side == Side::Left ? v.left : v.right;
    const XrEyeFov& f = fov[index_of(side)];
    const cv::Point2d want_dot = pixel_from_fov(f, kW, kH, ray_dot);
    const cv::Point2d got_dot = centroid(img, white, want_dot, 12);
    std::printf("measured: %s eye dot at (%.2f, %.2f), fov puts it at (%.2f, %.2f)\n",
                side == Side::Left ? "left" : "right", got_dot.x, got_dot.y, want_dot.x,
                want_dot.y);
    EXPECT_NEAR(got_dot.x, want_dot.x, 0.75);
    EXPECT_NEAR(got_dot.y, want_dot.y, 0.75);
    // The fingertip in this eye's frame (the left eye a baseline to the right eye's left).
    const glm::dvec3 tip =
        tip_right + (side == Side::Left ? glm::dvec3(in.baseline_m, 0, 0) : glm::dvec3(0.0));
    const cv::Point2d want_tip = pixel_from_fov(f, kW, kH, tip);
    EXPECT_TRUE(skin(
        img(static_cast<int>(std::lround(want_tip.y)), static_cast<int>(std::lround(want_tip.x)))))
        << "no skin at the fingertip's pixel " << want_tip;
    // The camera's field ends at tan 320/525 = 0.61 to the left; the display's at 0.87 or 0.75.
    const cv::Point2d edge = pixel_from_fov(f, kW, kH, {-320.0 / in.k.fx, -0.2, 1.0});
    const int row = static_cast<int>(std::lround(edge.y));
    const auto neutral = [](const cv::Vec3b& c) {
      return std::abs(c[0] - kOutsideCameraBgr[0]) <= 2 &&
             std::abs(c[1] - kOutsideCameraBgr[1]) <= 2;
    };
    EXPECT_TRUE(neutral(img(row, static_cast<int>(edge.x) - 2)))
        << img(row, static_cast<int>(edge.x) - 2);
    EXPECT_FALSE(neutral(img(row, static_cast<int>(edge.x) + 2)))
        << img(row, static_cast<int>(edge.x) + 2);
    EXPECT_TRUE(neutral(img(row, 0)));
  }
}

// Where OpenXR's projection puts a direction of the head (OpenXR's axes: x right, y up, z
// backwards) in an eye located at orientation q_HeadEye in the head with field of view `fov`:
// pixel centres at integers, top row 0. OpenXR's conventions throughout, so the camera
// convention's conversion (camera_rotation_from_openxr) is checked, not used.
cv::Point2d pixel_from_pose_and_fov(const XrEyeFov& fov, const glm::dquat& q_HeadEye, int width,
                                    int height, const glm::dvec3& d_Head) {
  const glm::dvec3 d = glm::conjugate(q_HeadEye) * d_Head;
  const double tan_right = d.x / -d.z, tan_up = d.y / -d.z;
  const double l = std::tan(fov.angle_left_rad), r = std::tan(fov.angle_right_rad);
  const double u = std::tan(fov.angle_up_rad), dn = std::tan(fov.angle_down_rad);
  return {width * (tan_right - l) / (r - l) - 0.5, height * (u - tan_up) / (u - dn) - 0.5};
}

glm::dvec3 openxr_from_camera(const glm::dvec3& p) { return {p.x, -p.y, -p.z}; }

// A headset with canted displays (Pimax, Index, Varjo) locates each eye turned outward in the head,
// here by 10 degrees: each eye shows the remote world turned accordingly. The eye video's dot, the
// drawn fingertip and the camera field's edge land where OpenXR's projection with the located
// orientation and fov puts them (drawn as if the eyes were parallel, the dot is some 50 px off).
TEST(OpenXrEyeFov, CantedEyesShowTheWorldWhereTheLocatedPoseAndFovPutIt) {
  const std::array<XrEyeFov, 2>& fov = kSimRuntimeFov;
  constexpr double kCant_rad = 10.0 * M_PI / 180.0;
  // Outward, as the project's runtime turns them with "view_cant_deg": left about +y, right -y.
  const std::array<glm::dquat, 2> q_HeadEye{glm::angleAxis(kCant_rad, glm::dvec3(0, 1, 0)),
                                            glm::angleAxis(-kCant_rad, glm::dvec3(0, 1, 0))};
  StereoView view(kW, kH);
  StereoViewInputs in = dot_video_in_fov();
  for (std::size_t eye = 0; eye < 2; ++eye) {
    in.R_CameraDisplay[eye] = camera_rotation_from_openxr(q_HeadEye[eye]);
  }
  const StereoViewImages v = view.render(in);
  ASSERT_EQ(v.right.size(), cv::Size(kW, kH));

  const glm::dvec3 ray_dot{(dot_px.x - in.k.cx) / in.k.fx, (dot_px.y - in.k.cy) / in.k.fy, 1.0};
  const auto white = [](const cv::Vec3b& c) { return c[0] > 200 && c[1] > 200 && c[2] > 200; };
  const auto skin = [](const cv::Vec3b& c) { return c[2] > c[0] + 30; };
  const auto neutral = [](const cv::Vec3b& c) {
    return std::abs(c[0] - kOutsideCameraBgr[0]) <= 2 && std::abs(c[1] - kOutsideCameraBgr[1]) <= 2;
  };
  for (const Side side : kSides) {
    SCOPED_TRACE(side == Side::Left ? "left eye" : "right eye");
    const std::size_t i = index_of(side);
    const cv::Mat3b& img = side == Side::Left ? v.left : v.right;
    const auto project = [&](const glm::dvec3& p_Camera) {
      return pixel_from_pose_and_fov(fov[i], q_HeadEye[i], kW, kH, openxr_from_camera(p_Camera));
    };
    const cv::Point2d want_dot = project(ray_dot);
    const cv::Point2d got_dot = centroid(img, white, want_dot, 12);
    std::printf(
        "measured: canted %s eye dot at (%.2f, %.2f), pose and fov put it at (%.2f, %.2f)\n",
        side == Side::Left ? "left" : "right", got_dot.x, got_dot.y, want_dot.x, want_dot.y);
    EXPECT_NEAR(got_dot.x, want_dot.x, 0.75);
    EXPECT_NEAR(got_dot.y, want_dot.y, 0.75);
    // The fingertip, from this eye's centre (the left eye a baseline to the right eye's left).
    const glm::dvec3 tip = in.hand.joints_camera[1][3] +
                           (side == Side::Left ? glm::dvec3(in.baseline_m, 0, 0) : glm::dvec3(0.0));
    const cv::Point2d want_tip = project(tip);
    EXPECT_TRUE(skin(
        img(static_cast<int>(std::lround(want_tip.y)), static_cast<int>(std::lround(want_tip.x)))))
        << "no skin at the fingertip's pixel " << want_tip;
    // The camera field's left edge (a plane through the head's y axis: a column of the turned
    // eye) with video to its right and the neutral grey to its left.
    const cv::Point2d edge = project({-(in.k.cx + 0.5) / in.k.fx, -0.2, 1.0});
    const int row = static_cast<int>(std::lround(edge.y));
    const int col = static_cast<int>(std::lround(edge.x));
    ASSERT_GE(col, 2);
    EXPECT_TRUE(neutral(img(row, col - 2))) << img(row, col - 2);
    EXPECT_FALSE(neutral(img(row, col + 2))) << img(row, col + 2);
  }
}

// The turned resampling, with the eyes' axes the cameras': the affine map's images bit for bit,
// video and depth, and a whole view drawn with R_CameraDisplay set to identity is the view drawn
// without it.
TEST(StereoView, UnturnedEyesAreTheImagesOfParallelEyesBitForBit) {
  const Intrinsics from = kinect_v1_intrinsics(640, 480);
  const Intrinsics to = pinhole_from_fov(XrEyeFov{-0.87, 0.75, 0.82, -0.87}, 320, 360);
  cv::Mat3b video(480, 640);
  cv::randu(video, 0, 256);
  cv::Mat1w depth(480, 640);
  cv::randu(depth, 0, 5000);
  const cv::Mat a = resample_pinhole(video, from, to, cv::INTER_LINEAR, kOutsideCameraBgr);
  const cv::Mat b =
      resample_pinhole(video, from, to, glm::dmat3(1.0), cv::INTER_LINEAR, kOutsideCameraBgr);
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0);
  const cv::Mat c = resample_pinhole(depth, from, to, cv::INTER_NEAREST);
  const cv::Mat d = resample_depth_turned(depth, from, to, glm::dmat3(1.0));
  ASSERT_EQ(c.size(), d.size());
  EXPECT_EQ(cv::norm(c, d, cv::NORM_INF), 0.0);

  StereoView view(320, 360);
  StereoViewInputs in;
  in.k = from;
  in.hand = reaching_hand();
  in.eye_bgr = {video, video};
  in.depth_mm = cv::Mat1w(480, 640, std::uint16_t{900});
  in.display_k = {to, to};
  const StereoViewImages parallel = view.render(in);
  // The same with the eyes turned, then set back: what the view drew turned does not linger.
  in.R_CameraDisplay = {camera_rotation_from_openxr(glm::angleAxis(0.1, glm::dvec3(0, 1, 0))),
                        camera_rotation_from_openxr(glm::angleAxis(-0.1, glm::dvec3(0, 1, 0)))};
  const StereoViewImages turned = view.render(in);
  EXPECT_GT(cv::norm(turned.right, parallel.right, cv::NORM_INF), 0.0);
  in.R_CameraDisplay = {glm::dmat3(1.0), glm::dmat3(1.0)};
  const StereoViewImages again = view.render(in);
  EXPECT_EQ(cv::norm(again.left, parallel.left, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(again.right, parallel.right, cv::NORM_INF), 0.0);
}

// A turned eye's depth is its own: a wall 2 m ahead of the camera, seen along the axis of an eye
// turned 10 degrees, is 2 m / cos 10 deg ahead of that eye (the depth the body's occlusion test
// compares with), and where the eye looks beyond the camera's field it has none.
TEST(StereoView, TurnedDepthIsAlongTheTurnedAxis) {
  const Intrinsics from = kinect_v1_intrinsics(640, 480);
  const Intrinsics to = pinhole_from_fov(XrEyeFov{-0.8, 0.8, 0.7, -0.7}, 400, 300);
  const cv::Mat1w wall(480, 640, std::uint16_t{2000});
  constexpr double kTurn_rad = 10.0 * M_PI / 180.0;
  const glm::dmat3 R_FromTo =
      camera_rotation_from_openxr(glm::angleAxis(-kTurn_rad, glm::dvec3(0, 1, 0)));
  const cv::Mat1w d = resample_depth_turned(wall, from, to, R_FromTo);
  ASSERT_EQ(d.size(), cv::Size(to.width, to.height));
  const int u = static_cast<int>(std::lround(to.cx)), v = static_cast<int>(std::lround(to.cy));
  std::printf("measured: on the turned axis %u mm (2000 / cos 10 deg = %.1f)\n", d(v, u),
              2000.0 / std::cos(kTurn_rad));
  EXPECT_NEAR(d(v, u), 2000.0 / std::cos(kTurn_rad), 2.0);
  // Every pixel: the wall's point along that pixel's ray, at the z the turned eye gives it.
  int checked = 0;
  for (int y = 0; y < to.height; y += 7)
    for (int x = 0; x < to.width; x += 7) {
      const glm::dvec3 d_To((x - to.cx) / to.fx, (y - to.cy) / to.fy, 1.0);
      const glm::dvec3 d_From = R_FromTo * d_To;
      const double col = from.fx * d_From.x / d_From.z + from.cx;
      if (col < 1.0 || col > from.width - 2.0) continue;
      const double row = from.fy * d_From.y / d_From.z + from.cy;
      if (row < 1.0 || row > from.height - 2.0) continue;
      // z_To of the wall's point on this ray: 2000 / d_From.z, within a pixel's slope.
      EXPECT_NEAR(d(y, x), 2000.0 / d_From.z, 3.0) << "at " << x << ", " << y;
      ++checked;
    }
  EXPECT_GT(checked, 500);
  // The turned eye's right edge sees beyond the camera's field (tan 0.8 + 10 deg): no depth.
  EXPECT_EQ(d(v, to.width - 1), 0);
}

// With the warp engaged the canted eyes still see the world where it is: the robot head captured
// the green dot (3 m ahead, on a wall) and the operator's head has since rolled 10 degrees; each
// eye, turned 8 degrees outward, shows the dot where that roll and its turn put it. (The roll
// about the camera's axis is, in a turned eye, a turn about another axis: warped about the
// camera's axes instead, the dot lands 12 px off.)
TEST(StereoView, WarpedCantedEyesShowTheWorldWhereTheHeadAndTheTurnPutIt) {
  StereoView view(640, 480);
  StereoViewInputs in = green_dot_ahead();
  constexpr double kCant_rad = 8.0 * M_PI / 180.0, kRoll_rad = 10.0 * M_PI / 180.0;
  in.display_k = {in.k, in.k};
  in.R_CameraDisplay = {
      camera_rotation_from_openxr(glm::angleAxis(kCant_rad, glm::dvec3(0, 1, 0))),
      camera_rotation_from_openxr(glm::angleAxis(-kCant_rad, glm::dvec3(0, 1, 0)))};
  in.R_BaseDepth = glm::dmat3(1.0);
  in.R_BaseDisplay = glm::dmat3(glm::rotate(glm::dmat4(1.0), kRoll_rad, glm::dvec3(0, 0, 1)));
  const StereoViewImages v = view.render(in);
  ASSERT_TRUE(v.warped);
  // The dot straight ahead of each eye's camera at capture (both eyes' videos are the one
  // picture), 3 m away; the head turns about the right eye's centre, the left eye at p_RightEye.
  const glm::dvec3 p_CaptureEye =
      3.0 * glm::dvec3((320.0 - in.k.cx) / in.k.fx, (240.0 - in.k.cy) / in.k.fy, 1.0);
  const glm::dmat3 R_DisplayCapture = glm::transpose(*in.R_BaseDisplay);
  const auto green = [](const cv::Vec3b& c) { return c[1] > 150 && c[0] < 80 && c[2] < 80; };
  for (const Side side : kSides) {
    SCOPED_TRACE(side == Side::Left ? "left eye" : "right eye");
    const std::size_t i = index_of(side);
    const glm::dvec3 p_RightEye =
        side == Side::Left ? glm::dvec3(-in.baseline_m, 0, 0) : glm::dvec3(0.0);
    // In the display's eye with the camera's axes, then in the turned eye.
    const glm::dvec3 p_DisplayEye = R_DisplayCapture * (p_CaptureEye + p_RightEye) - p_RightEye;
    const glm::dvec3 p_Eye = glm::transpose(in.R_CameraDisplay[i]) * p_DisplayEye;
    const cv::Point2d want(in.k.fx * p_Eye.x / p_Eye.z + in.k.cx,
                           in.k.fy * p_Eye.y / p_Eye.z + in.k.cy);
    const cv::Point2d got = centroid(side == Side::Left ? v.left : v.right, green, want, 20);
    std::printf("measured: warped canted %s eye dot at (%.2f, %.2f), want (%.2f, %.2f)\n",
                side == Side::Left ? "left" : "right", got.x, got.y, want.x, want.y);
    EXPECT_NEAR(got.x, want.x, 1.0);
    EXPECT_NEAR(got.y, want.y, 1.0);
  }
}

}  // namespace
}  // namespace telex::local
