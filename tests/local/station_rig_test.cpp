// SPDX-License-Identifier: MIT
// The rig file's keys reach the station's configuration, and a calibrated eye is undistorted and
// rectified into the view's pinhole camera.
#include <gtest/gtest.h>

#include <filesystem>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "telex/local/inputs/glove.h"
#include "telex/local/station/station.h"
#include "telex/local/view/stereo_view.h"

namespace telex::local {
namespace {

TEST(StationRig, TheExampleRigSetsBodiesHandsGlovesEyesAndChannels) {
  Rig rig = load_rig(std::filesystem::path(TELEX_SOURCE_DIR) / "docs" / "rig-example.json");
  rig.bodies.right_elbow = 6;
  rig.display_channel[1] = {4, 3, 2, 1, 0};
  rig.skin_rgb = {200, 150, 100};
  rig.body.hands[0].fingers[2].segment_m = {0.05, 0.03, 0.02};
  rig.X_RightEyeLeftEye->translation_m = {0.07, 0.0, 0.0};
  StationConfig cfg;
  apply_rig(rig, cfg);
  EXPECT_EQ(cfg.tracker.head_body_id, 1);
  EXPECT_EQ(cfg.tracker.left_hand_body_id, 4);
  EXPECT_EQ(cfg.tracker.left_shoulder_body_id, 5);
  EXPECT_EQ(cfg.tracker.right_elbow_body_id, 6);
  EXPECT_EQ(cfg.tracker.left_hand.fingers[2].segment_m, rig.body.hands[0].fingers[2].segment_m);
  EXPECT_TRUE(cfg.tracker.left_hand.left);
  EXPECT_FALSE(cfg.tracker.hand.left);
  EXPECT_EQ(cfg.tracker.hand.p_HeadCamera, rig.p_HeadCamera);
  ASSERT_TRUE(cfg.tracker.glove_range[1]);
  EXPECT_EQ(cfg.tracker.glove_range[1]->max, rig.glove[1]->max);
  EXPECT_FALSE(cfg.tracker.glove_range[0]);
  EXPECT_DOUBLE_EQ(cfg.stereo_baseline_m, 0.07);
  ASSERT_TRUE(cfg.eye_camera[0] && cfg.eye_camera[1]);
  EXPECT_EQ(cfg.eye_camera[0]->distortion, rig.eye[0]->distortion);
  EXPECT_EQ(cfg.display_channel[1], (std::array<int, 5>{4, 3, 2, 1, 0}));
  EXPECT_EQ(cfg.body.upper_arm_m, rig.body.upper_arm_m);
  EXPECT_EQ(cfg.skin_bgr, cv::Vec3b(100, 150, 200));
  EXPECT_EQ(cfg.display.gravity_grabber, rig.gravity_grabber);
}

TEST(StationRig, AGloveRangeOfTheWrongSensorCountIsAClearError) {
  GloveRange five{{0, 0, 0, 0, 0}, {1, 1, 1, 1, 1}};
  EXPECT_NO_THROW(GloveCalibration::from_range(five, 5, "rig"));
  try {
    GloveCalibration::from_range(five, 14, "the rig's glove range");
    FAIL() << "accepted 5 sensors for a 14-sensor glove";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("holds 5 sensors but the glove has 14"), std::string::npos)
        << e.what();
  }
}

// A point seen through the eye's lens (distorted, left eye also rotated) lands where the view's
// pinhole camera, oriented as the right eye, would see it.
TEST(EyeRectifier, ADistortedRotatedEyeLandsOnThePinholePixels) {
  const Intrinsics target{525.0, 525.0, 319.5, 239.5, 640, 480};
  CameraModel eye;
  eye.k = {540.0, 538.0, 322.0, 236.0, 640, 480};
  eye.distortion = {-0.25, 0.08, 0.001, -0.0005, 0.0};
  // The left eye is toed in by 2 degrees about y (p_right = R p_left).
  const double a = 2.0 * 3.14159265358979 / 180.0;
  const glm::dmat3 R_RightLeft(std::cos(a), 0.0, -std::sin(a), 0.0, 1.0, 0.0, std::sin(a), 0.0,
                               std::cos(a));  // columns
  // Points in the right-eye (target) orientation, drawn as dots where the left eye sees them.
  std::vector<cv::Point3d> pts;
  for (int y = -2; y <= 2; ++y)
    for (int x = -3; x <= 3; ++x) pts.push_back({0.12 * x, 0.12 * y, 1.0});
  cv::Matx33d R_LeftRight;  // rotates target-oriented points into the left eye's frame
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) R_LeftRight(r, c) = R_RightLeft[r][c];  // transpose
  cv::Vec3d rvec;
  cv::Rodrigues(R_LeftRight, rvec);
  std::vector<cv::Point2d> seen;
  const cv::Matx33d K(eye.k.fx, 0, eye.k.cx, 0, eye.k.fy, eye.k.cy, 0, 0, 1);
  cv::projectPoints(pts, rvec, cv::Vec3d(0, 0, 0), K, eye.distortion, seen);
  cv::Mat3b img(480, 640, cv::Vec3b(0, 0, 0));
  for (const auto& p : seen) cv::circle(img, p * 16, 3 * 16, {255, 255, 255}, cv::FILLED, 8, 4);

  EyeRectifier rect(eye, R_RightLeft);
  const cv::Mat3b out = rect.apply(img, target);
  ASSERT_EQ(out.size(), cv::Size(640, 480));
  for (const auto& p : pts) {
    const cv::Point2d want(target.fx * p.x / p.z + target.cx, target.fy * p.y / p.z + target.cy);
    // The dot's centroid in a window around where the pinhole puts it.
    const cv::Rect win(static_cast<int>(want.x) - 8, static_cast<int>(want.y) - 8, 17, 17);
    cv::Mat1b grey;
    cv::cvtColor(out(win & cv::Rect(0, 0, 640, 480)), grey, cv::COLOR_BGR2GRAY);
    const cv::Moments m = cv::moments(grey);
    ASSERT_GT(m.m00, 0.0) << "no dot near " << want;
    const cv::Point2d got(win.x + m.m10 / m.m00, win.y + m.m01 / m.m00);
    EXPECT_LT(cv::norm(got - want), 0.5) << "at " << want << " got " << got;
  }
  // Without the rectifier the dots are off by several pixels: the check above can fail.
  double worst = 0.0;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    const cv::Point2d want(target.fx * pts[i].x + target.cx, target.fy * pts[i].y + target.cy);
    worst = std::max(worst, cv::norm(seen[i] - want));
  }
  EXPECT_GT(worst, 10.0);
}

}  // namespace
}  // namespace telex::local
