// SPDX-License-Identifier: MIT
// The stereo view in a headset's eyes: each eye drawn in the field of view OpenXR submits, canted
// eyes turned as the located views say, the depth along the turned axis, and the warp with both.
#include <gtest/gtest.h>

#include <cmath>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <opencv2/imgproc.hpp>

#include "stereo_view_fixtures.h"
#include "telex/local/view/openxr_output.h"
#include "telex/local/view/stereo_view.h"

namespace telex::local {
namespace {

using test::green_dot_ahead;
using test::green_x;
using test::reaching_hand;

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
