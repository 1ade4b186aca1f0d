// SPDX-License-Identifier: MIT
// The stereo view's body and Fig. 7: a flat hand shows five separate fingers, the skin follows the
// video's brightness, a fingertip near the remote surface shades it, and the Fig. 7 panel holds a
// full normal map of the remote scene with a touch vector at the contact.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <glm/gtc/quaternion.hpp>
#include <opencv2/imgproc.hpp>
#include <set>

#include "analytic_depth.h"
#include "telex/haptics/hand_kinematics.h"
#include "telex/local/view/fig7_view.h"
#include "telex/local/view/stereo_view.h"

namespace telex::local {
namespace {

// A right hand held up flat 40 cm in front of the eyes, palm to the camera, fingers up: the hand
// frame's x (along the fingers) is the camera's -y, its y (the back of the hand) the camera's +z.
HandState flat_hand() {
  const glm::dmat3 R_CameraHand(glm::dvec3{0.0, -1.0, 0.0}, glm::dvec3{0.0, 0.0, 1.0},
                                glm::dvec3{-1.0, 0.0, 0.0});
  const Pose X_CameraWrist{{0.0, 0.06, 0.40}, glm::quat_cast(R_CameraHand)};
  const std::array<double, 5> straight{0.0, 0.0, 0.0, 0.0, 0.0};
  const HandPoints points = hand_forward(HandGeometry{}, X_CameraWrist, std::span(straight));
  HandState h;
  h.time_ns = 1;
  h.skeleton_valid = true;
  h.wrist_camera = points.wrist;
  for (std::size_t f = 0; f < kFingerCount; ++f) {
    h.joints_camera[f] = points.joints[f];
    h.tips[f].valid = true;
    h.tips[f].finger = static_cast<int>(f);
    h.tips[f].p_CameraFingertip = points.joints[f][3];
  }
  return h;
}

bool skin(const cv::Vec3b& c) { return c[2] > c[0] + 25; }

cv::Point pixel(const Intrinsics& k, const glm::dvec3& p) {
  return {static_cast<int>(std::lround(k.fx * p.x / p.z + k.cx)),
          static_cast<int>(std::lround(k.fy * p.y / p.z + k.cy))};
}

StereoViewImages render_hand(StereoView& view, const HandState& hand, cv::Vec3b background,
                             cv::Size eye_size = {}) {
  StereoViewInputs in;
  in.k = kinect_v1_intrinsics(640, 480);
  in.eye_size = eye_size;
  in.hand = hand;
  in.eye_bgr = {cv::Mat3b(480, 640, background), cv::Mat3b(480, 640, background)};
  return view.render(in);
}

// At 640x480 the body is marched at the eye's resolution, at 1280x720 at half of it.
void expect_five_separate_fingertips(cv::Size eye_size) {
  StereoView view(eye_size.width, eye_size.height);
  const HandState hand = flat_hand();
  const StereoViewImages v = render_hand(view, hand, {118, 118, 118}, eye_size);
  const Intrinsics k = eye_intrinsics(kinect_v1_intrinsics(640, 480), eye_size);
  // Skin pixels within 0.6 of the fingers' spacing of any fingertip: discs of neighbouring tips
  // overlap, so fingers joined by skin (a mitten) would make one component of two tips.
  std::array<cv::Point, kFingerCount> tips{};
  for (std::size_t f = 0; f < kFingerCount; ++f) tips[f] = pixel(k, hand.joints_camera[f][3]);
  const double spacing_px = cv::norm(tips[2] - tips[3]);
  ASSERT_GT(spacing_px, 15.0);
  const double reach = 0.6 * spacing_px;
  cv::Mat1b mask(v.right.size(), std::uint8_t{0});
  for (int y = 0; y < mask.rows; ++y)
    for (int x = 0; x < mask.cols; ++x) {
      if (!skin(v.right(y, x))) continue;
      for (const cv::Point& t : tips)
        if (std::hypot(x - t.x, y - t.y) < reach) mask(y, x) = 255;
    }
  cv::Mat1i labels;
  cv::connectedComponents(mask, labels, 8);
  std::set<int> seen;
  for (std::size_t f = 0; f < kFingerCount; ++f) {
    const int label = labels(tips[f]);
    EXPECT_NE(label, 0) << "fingertip " << f << " is not drawn at its pixel";
    seen.insert(label);
  }
  EXPECT_EQ(seen.size(), kFingerCount) << "fingertips share a blob";
}

TEST(StereoBody, AFlatHandShowsFiveFingertipsAsFiveSeparateBlobs) {
  expect_five_separate_fingertips({640, 480});
  expect_five_separate_fingertips({1280, 720});
}

TEST(StereoBody, TheSkinIsLitToTheVideosBrightness) {
  StereoView view(640, 480);
  const HandState hand = flat_hand();
  const Intrinsics k = kinect_v1_intrinsics(640, 480);
  const cv::Point palm = pixel(k, (hand.joints_camera[2][0] + hand.wrist_camera) * 0.5);
  const auto luma = [&](cv::Vec3b bg) {
    const cv::Mat3b img = render_hand(view, hand, bg).right;
    const cv::Scalar m = cv::mean(img(cv::Rect(palm.x - 4, palm.y - 4, 9, 9)));
    return 0.114 * m[0] + 0.587 * m[1] + 0.299 * m[2];
  };
  const double dark = luma({30, 30, 30}), mid = luma({118, 118, 118}),
               bright = luma({220, 220, 220});
  EXPECT_LT(dark, 0.7 * mid);
  EXPECT_GT(bright, 1.15 * mid);
}

TEST(StereoBody, AFingertipNearTheSurfaceShadesItAndOneFarFromItDoesNot) {
  StereoRenderer r(640, 480);
  EyeView eye;
  eye.k = kinect_v1_intrinsics(640, 480);
  eye.background = cv::Mat3b(480, 640, cv::Vec3b(160, 160, 160));
  eye.depth_mm = cv::Mat1w(480, 640, std::uint16_t{500});
  const glm::dvec3 tip{0.02, 0.01, 0.49};  // 1 cm in front of the wall
  const cv::Point at = pixel(eye.k, tip);
  eye.fingertips = {tip};
  const cv::Mat3b near = r.render(eye, {});
  EXPECT_LT(near(at)[1], 110) << "right under the fingertip";
  EXPECT_GT(near(at + cv::Point(120, 0))[1], 155) << "15 cm away";
  eye.fingertips = {glm::dvec3{0.02, 0.01, 0.35}};  // 15 cm off the wall
  EXPECT_GT(r.render(eye, {})(at)[1], 155);
}

using test::two_planes;

TEST(StereoFig7, ThePanelHoldsAFullNormalMapAndATouchVectorAtTheContact) {
  StereoView view(1280, 720);
  StereoViewInputs in;
  in.k = kinect_v1_intrinsics(640, 480);
  in.eye_size = {1280, 720};
  in.fig7 = true;
  const glm::dvec3 n_right = glm::normalize(glm::dvec3{0.5, 0.0, -1.0});
  in.depth_mm = two_planes(in.k, n_right);
  // The haptic path's surface: normals only in a fingertip window, as the default ROI builds.
  Surface s;
  s.intrinsics = in.k;
  s.normals = cv::Mat3f(480, 640, cv::Vec3f(0.0f, 0.0f, 0.0f));
  s.normals(cv::Rect(100, 100, 32, 32)).setTo(cv::Vec3f(0.0f, 0.0f, -1.0f));
  in.surface = &s;
  const glm::dvec3 god{-0.10, 0.05, 0.80};  // on the wall
  in.forces[1].contact = true;
  in.forces[1].p_ModelProxy = god;
  in.forces[1].normal_Model = {0.0, 0.0, -1.0};
  in.forces[1].normal_force_N = 2.0;
  in.forces[1].tangential_force_N = {0.5, 0.0, 0.0};
  in.forces[1].force_N = {0.5, 0.0, -2.0};
  const StereoViewImages v = view.render(in);
  ASSERT_EQ(v.fig7.size(), cv::Size(2560, 720));
  const cv::Mat3b panel = v.fig7(cv::Rect(1280, 0, 1280, 720));
  int lit = 0;
  for (int y = 0; y < panel.rows; ++y)
    for (int x = 0; x < panel.cols; ++x) lit += panel(y, x) != cv::Vec3b(0, 0, 0);
  EXPECT_GT(lit, panel.rows * panel.cols * 9 / 10);
  // The colours colorize_normals gives each plane's normal ((n + 1) / 2, as BGR = z, y, x).
  const auto expect_normal = [&](cv::Point p, const glm::dvec3& n) {
    const cv::Vec3b c = panel(p);
    EXPECT_NEAR(c[0], (n.z + 1.0) * 127.5, 12.0) << p;
    EXPECT_NEAR(c[1], (n.y + 1.0) * 127.5, 12.0) << p;
    EXPECT_NEAR(c[2], (n.x + 1.0) * 127.5, 12.0) << p;
  };
  expect_normal({300, 200}, {0.0, 0.0, -1.0});
  expect_normal({1000, 500}, n_right);
  // The god-point's ring and the force arrow (yellow) at the contact's pixel.
  const Intrinsics k_eye = eye_intrinsics(in.k, in.eye_size);
  const cv::Point at = pixel(k_eye, god);
  int yellow = 0;
  for (int y = at.y - 20; y <= at.y + 20; ++y)
    for (int x = at.x - 20; x <= at.x + 20; ++x) {
      const cv::Vec3b c = panel(y, x);
      yellow += c[0] < 60 && c[1] > 180 && c[2] > 220;
    }
  EXPECT_GT(yellow, 40);
  // Away from the contact the panel has no yellow.
  int far_yellow = 0;
  for (int y = 500; y < 540; ++y)
    for (int x = 1000; x < 1040; ++x) {
      const cv::Vec3b c = panel(y, x);
      far_yellow += c[0] < 60 && c[1] > 180 && c[2] > 220;
    }
  EXPECT_EQ(far_yellow, 0);
}

}  // namespace
}  // namespace telex::local
