// SPDX-License-Identifier: MIT
// The overview (view.png) in pixels: its normal-map inset shows the remote scene's full-frame
// normals the stereo view computed for display, with the haptic path's fingertip windows outlined
// on it, not the windows alone on black.
#include "telex/local/view/operator_view.h"

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/imgproc.hpp>

#include "analytic_depth.h"
#include "telex/local/view/stereo_view.h"

namespace telex::local {
namespace {

constexpr int kW = 640, kH = 480;
const cv::Vec3b kOutlineBgr(0, 230, 255);  // operator_view.cpp's window outline
const cv::Rect kWindow(200, 150, 48, 48);  // the fingertip window, depth pixels

// A wall 80 cm away on the left half and a plane turned 27 deg about the vertical on the right.
cv::Mat1w two_planes(const Intrinsics& k) {
  return test::two_planes(k, glm::normalize(glm::dvec3{0.5, 0.0, -1.0}));
}

// The haptic path's surface with the default region of interest: normals in one window only.
Surface windowed_surface(const Intrinsics& k, const cv::Rect& window) {
  Surface s;
  s.intrinsics = k;
  s.normals = cv::Mat3f(k.height, k.width, cv::Vec3f(0.0f, 0.0f, 0.0f));
  if (!window.empty()) s.normals(window).setTo(cv::Vec3f(0.0f, 0.0f, -1.0f));
  return s;
}

// The overview as the station's view thread composes it: the stereo view draws the pair and
// computes the normals it shows; the overview's inset takes those.
cv::Mat3b overview(const Surface& s, const cv::Mat1w& depth_mm, bool view_normals) {
  StereoView view(kW, kH);
  StereoViewInputs in;
  in.k = s.intrinsics;
  in.depth_mm = depth_mm;
  in.surface = &s;
  in.eye_bgr = {cv::Mat3b(kH, kW, cv::Vec3b(90, 90, 90)), cv::Mat3b(kH, kW, cv::Vec3b(90, 90, 90))};
  const StereoViewImages v = view.render(in);
  EXPECT_EQ(v.normals.size(), depth_mm.size());
  ViewInputs vi;
  vi.camera_bgr = cv::Mat3b(kH, kW, cv::Vec3b(90, 90, 90));
  vi.surface = &s;
  vi.depth_mm = depth_mm;
  if (view_normals) vi.normals = v.normals;
  return render_operator_view(vi);
}

// The inset: top right, a quarter of the image's width and height, 4 px in.
cv::Mat3b inset_of(const cv::Mat3b& img) {
  return img(cv::Rect(img.cols - img.cols / 4 - 4, 4, img.cols / 4, img.rows / 4));
}

double lit_fraction(const cv::Mat3b& img) {
  int lit = 0;
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) lit += img(y, x) != cv::Vec3b(0, 0, 0);
  return static_cast<double>(lit) / (img.rows * img.cols);
}

TEST(OperatorView, TheInsetShowsTheFullNormalMapWithTheFingertipWindowOutlined) {
  const Intrinsics k = kinect_v1_intrinsics(kW, kH);
  const cv::Mat1w depth = two_planes(k);
  const Surface s = windowed_surface(k, kWindow);
  const cv::Mat3b inset = inset_of(overview(s, depth, true));
  ASSERT_EQ(inset.size(), cv::Size(160, 120));
  EXPECT_GT(lit_fraction(inset), 0.9);
  // Both planes' normals, in colorize_normals' colours ((n + 1) / 2 as BGR = z, y, x): the wall's
  // (0, 0, -1) on the left, the turned plane's on the right.
  const cv::Vec3b wall = inset(90, 20), turned = inset(90, 140);
  EXPECT_NEAR(wall[0], 0, 12);
  EXPECT_NEAR(wall[2], 127, 12);
  EXPECT_NEAR(turned[2], (0.5 / std::sqrt(1.25) + 1.0) * 127.5, 12);
  // The window's outline at a quarter of its depth pixels, and nowhere else.
  const double s_inset = 0.25;
  const cv::Rect want(static_cast<int>(kWindow.x * s_inset), static_cast<int>(kWindow.y * s_inset),
                      static_cast<int>(kWindow.width * s_inset),
                      static_cast<int>(kWindow.height * s_inset));
  int on_border = 0, elsewhere = 0;
  for (int y = 0; y < inset.rows; ++y)
    for (int x = 0; x < inset.cols; ++x) {
      if (inset(y, x) != kOutlineBgr) continue;
      const bool border = (std::abs(x - want.x) <= 1 || std::abs(x - want.br().x) <= 1 ||
                           std::abs(y - want.y) <= 1 || std::abs(y - want.br().y) <= 1) &&
                          x >= want.x - 1 && x <= want.br().x + 1 && y >= want.y - 1 &&
                          y <= want.br().y + 1;
      (border ? on_border : elsewhere)++;
    }
  EXPECT_GE(on_border, 4 * want.width - 4) << "the fingertip window is not outlined";
  EXPECT_EQ(elsewhere, 0);
}

// What issue 29 saw: the surface's own normals alone are the window on black. The test above
// tells the two apart.
TEST(OperatorView, TheSurfacesOwnNormalsAloneAreMostlyBlack) {
  const Intrinsics k = kinect_v1_intrinsics(kW, kH);
  const cv::Mat1w depth = two_planes(k);
  const Surface s = windowed_surface(k, kWindow);
  EXPECT_LT(lit_fraction(inset_of(overview(s, depth, false))), 0.1);
}

// --full-frame: the surface's normals cover the scene, the view shows them as they are and has no
// window to outline.
TEST(OperatorView, AFullFrameSurfaceIsShownWithoutOutlines) {
  const Intrinsics k = kinect_v1_intrinsics(kW, kH);
  const cv::Mat1w depth = two_planes(k);
  const Surface s = windowed_surface(k, cv::Rect(0, 0, kW, kH));
  const cv::Mat3b inset = inset_of(overview(s, depth, true));
  EXPECT_GT(lit_fraction(inset), 0.9);
  int outline = 0;
  for (int y = 0; y < inset.rows; ++y)
    for (int x = 0; x < inset.cols; ++x) outline += inset(y, x) == kOutlineBgr;
  EXPECT_EQ(outline, 0);
}

}  // namespace
}  // namespace telex::local
