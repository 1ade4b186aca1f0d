// SPDX-License-Identifier: MIT
// The stereo view's renderer, headless on Mesa's EGL: the remote scene hides the body where it is
// nearer (both eyes), the eyes see a point at depth Z with the disparity f B / Z, and bad sizes or
// a missing EGL name themselves.
#include "telex/local/view/stereo_renderer.h"

#include <epoxy/gl.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <iostream>
#include <memory>

namespace telex::local {
namespace {

constexpr double kBaseline = 0.064;

EyeView eye(bool left, const cv::Mat1w& depth) {
  EyeView e;
  e.k = kinect_v1_intrinsics(640, 480);
  e.p_RightEye = left ? glm::dvec3{-kBaseline, 0.0, 0.0} : glm::dvec3{0.0};
  e.background = cv::Mat3b(480, 640, cv::Vec3b(40, 40, 40));
  e.depth_mm = depth;
  return e;
}

// Where a point of the right eye's frame lands in an eye.
cv::Point2d project(const EyeView& e, const glm::dvec3& p_Right) {
  const glm::dvec3 p = p_Right - e.p_RightEye;
  return {e.k.fx * p.x / p.z + e.k.cx, e.k.fy * p.y / p.z + e.k.cy};
}

TEST(StereoRenderer, TheRemoteSceneHidesAFingertipBehindItInBothEyes) {
  StereoRenderer r(640, 480);
  std::cout << "GL renderer: " << r.gl_renderer() << "\n";
  // A wall at 2 m with a box face at 0.8 m over the middle of both eyes' views.
  cv::Mat1w depth(480, 640, std::uint16_t{2000});
  depth(cv::Rect(170, 90, 300, 300)).setTo(800);
  const cv::Vec3b skin(150, 170, 230);
  for (const bool left : {false, true}) {
    const EyeView e = eye(left, depth);
    for (const double z : {1.0, 0.6}) {
      const glm::dvec3 tip{0.0, 0.0, z};
      const std::vector<Capsule> body{{tip, tip, 0.012, skin}};
      const cv::Mat3b img = r.render(e, body);
      const cv::Point2d px = project(e, tip);
      const cv::Vec3b got = img(static_cast<int>(px.y), static_cast<int>(px.x));
      if (z > 0.8)
        EXPECT_EQ(got, e.background(0, 0)) << (left ? "left" : "right") << " eye, behind";
      else
        EXPECT_NE(got, e.background(0, 0)) << (left ? "left" : "right") << " eye, in front";
      // Outside the sphere's image the background is untouched.
      EXPECT_EQ(img(10, 10), e.background(10, 10));
    }
  }
  // Without depth nothing hides it.
  const EyeView open = eye(false, {});
  const cv::Mat3b img =
      r.render(open, std::vector<Capsule>{{{0, 0, 1.0}, {0, 0, 1.0}, 0.012, skin}});
  EXPECT_NE(img(240, 320), open.background(240, 320));
}

// A 1280x720 eye marches the body at half its resolution and composites it: the remote depth must
// still hide it to the eye pixel, the eye's own image must stay whole (the very first render
// included), and the body must land where the intrinsics put it.
TEST(StereoRenderer, AtHalfTheBodysResolutionTheSceneStillHidesItToThePixel) {
  for (const int divisor : {2, 3}) {
    StereoRenderer r(640, 480);
    r.set_body_divisor(divisor);
    // A box face at 0.8 m over the eye's left half, a wall at 2 m on the right; a ball at 1 m
    // across the edge (16 px radius).
    cv::Mat1w depth(480, 640, std::uint16_t{2000});
    depth.colRange(0, 320).setTo(800);
    const EyeView e = eye(false, depth);
    const glm::dvec3 c{0.0, 0.0, 1.0};
    const cv::Point2d px = project(e, c);
    const std::vector<Capsule> body{{c, c, 0.03, {150, 170, 230}}};
    const cv::Mat3b img = r.render(e, body);
    const int row = static_cast<int>(px.y);
    EXPECT_EQ(img(10, 10), e.background(10, 10)) << divisor;
    EXPECT_EQ(img(470, 630), e.background(470, 630)) << divisor;
    for (int x = 300; x < 320; ++x) EXPECT_EQ(img(row, x), e.background(row, x)) << x;
    for (int x = 320; x < static_cast<int>(px.x) + 10; ++x)
      EXPECT_GT(img(row, x)[2], img(row, x)[0] + 25) << "skin at " << x << ", divisor " << divisor;
    // The ball's bottom edge (in its shadow side): its lowest pixel within 3/4 of a low-resolution
    // pixel of the projection's (the bilinear blend reaches out that far).
    const int col = static_cast<int>(px.x) + 8;
    int lowest = -1;
    for (int y = row; y < 480; ++y)
      if (img(y, col) != e.background(y, col)) lowest = y;
    const double dx = (col - e.k.cx) / e.k.fx;
    const double half_chord = std::sqrt(0.03 * 0.03 - dx * dx * 1.0) * e.k.fy;
    EXPECT_NEAR(lowest, px.y + half_chord, 0.75 * divisor) << divisor;
  }
  StereoRenderer r(640, 480);
  EXPECT_THROW(r.set_body_divisor(9), std::invalid_argument);
}

// The composite shades only the tiles each capsule's own bounds cover, not the rectangle around
// them all: two balls in opposite corners with a diagonal band of wall between them come out as
// each alone does, pixel for pixel, and the band between them stays the eye's own image.
TEST(StereoRenderer, AtHalfTheBodysResolutionBallsFarApartAreEachDrawnWhole) {
  StereoRenderer r(640, 480);
  r.set_body_divisor(2);
  cv::Mat1w depth(480, 640, std::uint16_t{2000});
  const EyeView e = eye(false, depth);
  const cv::Vec3b skin{150, 170, 230};
  const glm::dvec3 a{-0.45, -0.3, 1.0}, b{0.45, 0.3, 1.0};
  const std::vector<Capsule> both{{a, a, 0.05, skin}, {b, b, 0.05, skin}};
  const cv::Mat3b img = r.render(e, both);
  const cv::Mat3b only_a = r.render(e, std::vector<Capsule>{both[0]});
  const cv::Mat3b only_b = r.render(e, std::vector<Capsule>{both[1]});
  int drawn_a = 0, drawn_b = 0;
  for (int y = 0; y < 480; ++y)
    for (int x = 0; x < 640; ++x) {
      const bool in_a = only_a(y, x) != e.background(y, x);
      const bool in_b = only_b(y, x) != e.background(y, x);
      ASSERT_FALSE(in_a && in_b) << "the balls overlap at " << x << ", " << y;
      const cv::Vec3b want = in_a ? only_a(y, x) : in_b ? only_b(y, x) : e.background(y, x);
      ASSERT_EQ(img(y, x), want) << "at " << x << ", " << y;
      drawn_a += in_a ? 1 : 0;
      drawn_b += in_b ? 1 : 0;
    }
  // Each ball (some 26 px in radius) is there, and the centre between them is untouched.
  EXPECT_GT(drawn_a, 2000);
  EXPECT_GT(drawn_b, 2000);
  EXPECT_EQ(img(240, 320), e.background(240, 320));
}

// Centroid of the pixels that differ from the background.
cv::Point2d centroid(const cv::Mat3b& img, const cv::Vec3b& background) {
  double sx = 0, sy = 0, n = 0;
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x)
      if (img(y, x) != background) {
        sx += x;
        sy += y;
        ++n;
      }
  return n > 0 ? cv::Point2d(sx / n, sy / n) : cv::Point2d(-1, -1);
}

TEST(StereoRenderer, AFingertipAtDepthZHasTheDisparityFBOverZ) {
  StereoRenderer r(640, 480);
  for (const double z : {0.4, 0.8, 1.5, 3.0}) {
    const glm::dvec3 tip{0.05, -0.03, z};
    const std::vector<Capsule> body{{tip, tip, 0.004 * z, {255, 255, 255}}};
    const EyeView right = eye(false, {}), left = eye(true, {});
    const cv::Point2d cr = centroid(r.render(right, body), right.background(0, 0));
    const cv::Point2d cl = centroid(r.render(left, body), left.background(0, 0));
    ASSERT_GE(cr.x, 0.0) << z;
    ASSERT_GE(cl.x, 0.0) << z;
    const double expected = right.k.fx * kBaseline / z;
    EXPECT_NEAR(cl.x - cr.x, expected, 1.0) << "Z = " << z;
    EXPECT_NEAR(cl.y, cr.y, 0.5) << "Z = " << z;
    // And each lands where the intrinsics put it (OpenCV's pixel centres).
    EXPECT_NEAR(cr.x, project(right, tip).x, 0.5) << z;
    EXPECT_NEAR(cr.y, project(right, tip).y, 0.5) << z;
  }
}

// --view openxr's path: the eye stays on the GPU (no read-back) and is blitted into a texture of
// another size (a swapchain image) with GL's bottom-up rows: the image's top is the texture's last
// row.
TEST(StereoRenderer, BlitToPutsTheEyeIntoATextureScaledAndBottomUp) {
  StereoRenderer r(640, 480);  // its context is current on this thread
  EyeView e = eye(false, {});
  e.background.rowRange(0, 240).setTo(cv::Vec3b(0, 0, 255));    // top: red
  e.background.rowRange(240, 480).setTo(cv::Vec3b(255, 0, 0));  // bottom: blue
  e.read_back = false;
  EXPECT_TRUE(r.render(e, {}).empty());
  GLuint tex = 0;
  glGenTextures(1, &tex);
  glBindTexture(GL_TEXTURE_2D, tex);
  glTexStorage2D(GL_TEXTURE_2D, 1, GL_RGBA8, 320, 360);
  r.blit_to(tex, 320, 360);
  cv::Mat4b got(360, 320);
  glBindTexture(GL_TEXTURE_2D, tex);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glGetTexImage(GL_TEXTURE_2D, 0, GL_RGBA, GL_UNSIGNED_BYTE, got.data);
  glDeleteTextures(1, &tex);
  EXPECT_EQ(glGetError(), static_cast<GLenum>(GL_NO_ERROR));
  // RGBA: row 0 is the bottom of the picture (blue), the last row its top (red).
  EXPECT_EQ(got(5, 160), cv::Vec4b(0, 0, 255, 255));
  EXPECT_EQ(got(354, 160), cv::Vec4b(255, 0, 0, 255));
}

TEST(StereoRenderer, BadSizesAreRefusedWithTheSizes) {
  EXPECT_THROW(StereoRenderer(0, 480), std::invalid_argument);
  StereoRenderer r(320, 240);
  EyeView e = eye(false, {});  // 640x480 intrinsics
  try {
    r.render(e, {});
    FAIL();
  } catch (const std::invalid_argument& ex) {
    EXPECT_NE(std::string(ex.what()).find("640x480"), std::string::npos) << ex.what();
  }
  e.k = kinect_v1_intrinsics(320, 240);
  e.background = cv::Mat3b(100, 100);
  EXPECT_THROW(r.render(e, {}), std::invalid_argument);
}

TEST(StereoRenderer, TwoOnOneThreadEachDrawsWithItsOwnContext) {
  auto first = std::make_unique<StereoRenderer>(320, 240);
  StereoRenderer second(640, 480);
  EyeView small = eye(false, {});
  small.k = kinect_v1_intrinsics(320, 240);
  small.background = cv::Mat3b(240, 320, cv::Vec3b(40, 40, 40));
  EXPECT_EQ(first->render(small, {}).size(), cv::Size(320, 240));
  first.reset();  // its end must not take the second's context away
  EXPECT_EQ(second.render(eye(false, {}), {}).size(), cv::Size(640, 480));
}

TEST(StereoRendererDeathTest, NoEglVendorIsAClearError) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  // glvnd with no vendor library: no EGL display at all (a fresh process, so EGL is not loaded).
  EXPECT_EXIT(
      {
        setenv("__EGL_VENDOR_LIBRARY_FILENAMES", "/nonexistent/egl_vendor.json", 1);
        try {
          StereoRenderer r(64, 48);
        } catch (const std::runtime_error& e) {
          std::cerr << e.what() << "\n";
          std::exit(3);
        }
        std::exit(0);
      },
      testing::ExitedWithCode(3), "no EGL display.*libegl-mesa0");
}

}  // namespace
}  // namespace telex::local
