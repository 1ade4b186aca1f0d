// SPDX-License-Identifier: MIT
// The calibration library on rendered boards with known answers (blur, noise, distortion): each
// eye's intrinsics, the stereo extrinsics and the depth-to-eye pose, and its error cases.
#include "telex/calib/calibrate.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "telex/calib/render.h"

namespace telex::calib {
namespace {

constexpr double kDeg = 180.0 / 3.14159265358979323846;

struct Corners {
  ViewCorners left, right, ir;
  std::vector<cv::Mat1w> depth;
};

// Views where all three cameras found the board.
Corners detect_all(const std::vector<RenderedView>& views, const BoardSpec& b) {
  Corners c;
  for (const RenderedView& v : views) {
    const CornerDetection l = detect_corners(v.left, b), r = detect_corners(v.right, b),
                          i = detect_corners(v.ir, b);
    if (!l.found || !r.found || !i.found) continue;
    c.left.push_back(l.corners_px);
    c.right.push_back(r.corners_px);
    c.ir.push_back(i.corners_px);
    c.depth.push_back(v.depth_mm);
  }
  return c;
}

double percent(double got, double want) { return 100.0 * (got - want) / want; }

TEST(FitRigidTransform, RecoversAKnownTransform) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> u(-0.5, 0.5);
  const RigidTransform truth = example_render_rig().X_RightEyeDepth;
  std::vector<cv::Point3d> a, b;
  for (int i = 0; i < 40; ++i) {
    const glm::dvec3 p(u(rng), u(rng), 1.0 + u(rng));
    const glm::dvec3 q = apply(truth, p);
    a.emplace_back(p.x, p.y, p.z);
    b.emplace_back(q.x, q.y, q.z);
  }
  const RigidTransform got = fit_rigid_transform(a, b);
  EXPECT_LT(glm::length(got.translation_m - truth.translation_m), 1e-12);
  EXPECT_LT(rotation_angle_between_rad(got.rotation, truth.rotation), 1e-12);
  EXPECT_NEAR(glm::determinant(got.rotation), 1.0, 1e-12);
}

TEST(FitRigidTransform, RejectsTooFewMismatchedAndCollinearPoints) {
  const std::vector<cv::Point3d> two{{0, 0, 1}, {1, 0, 1}};
  EXPECT_THROW(fit_rigid_transform(two, two), std::invalid_argument);
  const std::vector<cv::Point3d> line{{0, 0, 1}, {1, 0, 1}, {2, 0, 1}, {3, 0, 1}};
  EXPECT_THROW(fit_rigid_transform(line, line), std::invalid_argument);
  const std::vector<cv::Point3d> three{{0, 0, 1}, {1, 0, 1}, {0, 1, 1}};
  EXPECT_THROW(fit_rigid_transform(three, line), std::invalid_argument);
}

TEST(RotationAngle, MatchesTheRotationVector) {
  const RigidTransform x = example_render_rig().X_RightEyeLeftEye;
  const double angle = cv::norm(rotation_vector_rad(x.rotation));
  EXPECT_NEAR(rotation_angle_between_rad(glm::dmat3(1.0), x.rotation), angle, 1e-12);
  EXPECT_NEAR(rotation_angle_between_rad(x.rotation, x.rotation), 0.0, 1e-12);
  const RigidTransform back = compose(inverse(x), x);
  EXPECT_LT(glm::length(back.translation_m), 1e-15);
}

// Corners where the truth projects them (no image): for the error cases.
Corners projected_corners(const RenderRig& rig, const BoardSpec& b, int count) {
  const std::vector<RenderCamera> cams{{rig.left, inverse(rig.X_RightEyeLeftEye)},
                                       {rig.right, RigidTransform{}},
                                       {rig.depth, inverse(rig.X_RightEyeDepth)}};
  RenderStyle one;
  one.supersample = 1;
  const BoardRenderer l(rig.left, b, one), r(rig.right, b, one), d(rig.depth, b, one);
  Corners c;
  for (const RigidTransform& X_RightEyeBoard : random_board_poses(b, cams, count, 4)) {
    for (auto [list, renderer, X_CameraRig] : {std::tuple{&c.left, &l, cams[0].X_CameraRig},
                                               std::tuple{&c.right, &r, cams[1].X_CameraRig},
                                               std::tuple{&c.ir, &d, cams[2].X_CameraRig}}) {
      std::vector<cv::Point2f> px;
      for (const cv::Point3f& p : board_points(b)) {
        const cv::Point2d q =
            renderer->project(apply(compose(X_CameraRig, X_RightEyeBoard), {p.x, p.y, p.z}));
        px.emplace_back(static_cast<float>(q.x), static_cast<float>(q.y));
      }
      list->push_back(px);
    }
  }
  return c;
}

TEST(Calibrate, ErrorCases) {
  const BoardSpec b = parse_board("9x6", 30.0);
  const RenderRig rig = example_render_rig();
  const Corners c = projected_corners(rig, b, 6);
  const ViewCorners four(c.left.begin(), c.left.begin() + 4);
  const ViewCorners four_r(c.right.begin(), c.right.begin() + 4);
  EXPECT_THROW(calibrate_camera(four, b, {640, 480}), CalibrationError);
  EXPECT_THROW(calibrate_stereo(four, four_r, b, {640, 480}, {640, 480}), CalibrationError);
  EXPECT_THROW(calibrate_stereo(c.left, four_r, b, {640, 480}, {640, 480}), std::invalid_argument);
  ViewCorners short_view = c.left;
  short_view[2].pop_back();
  EXPECT_THROW(calibrate_camera(short_view, b, {640, 480}), std::invalid_argument);
  // The same images for both eyes: no baseline.
  try {
    calibrate_stereo(c.left, c.left, b, {640, 480}, {640, 480});
    ADD_FAILURE() << "identical eyes were calibrated";
  } catch (const CalibrationError& e) {
    EXPECT_NE(std::string(e.what()).find("1 mm"), std::string::npos) << e.what();
  }
  EXPECT_THROW(calibrate_depth_eye(four, four_r, b, rig.depth.k, rig.right), CalibrationError);
  EXPECT_THROW(calibrate_depth_eye(c.ir, c.right, b, rig.depth.k, rig.right,
                                   {cv::Mat1w(480, 640, static_cast<std::uint16_t>(700))}),
               std::invalid_argument);
  // Exact corners: the depth-eye pose is exact to float rounding.
  const DepthEyeCalibration d = calibrate_depth_eye(c.ir, c.right, b, rig.depth.k, rig.right);
  EXPECT_LT(glm::length(d.X_RightEyeDepth.translation_m - rig.X_RightEyeDepth.translation_m), 1e-5);
  EXPECT_LT(d.residual_mm, 0.01);
}

// One rendered set for the accuracy tests: 14 views, 9x6 board of 30 mm squares, blur 0.8 px,
// noise 2 grey levels (IR: 1.0 px, 3 levels, dimmer), depth noise 1 mm. Two tests (each ctest
// case is its own process, so each renders the set once).
class RenderedBoards : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    board_ = parse_board("9x6", 30.0);
    rig_ = example_render_rig();
    corners_ = detect_all(render_views(rig_, board_, 14, 21), board_);
  }
  static BoardSpec board_;
  static RenderRig rig_;
  static Corners corners_;
};
BoardSpec RenderedBoards::board_;
RenderRig RenderedBoards::rig_;
Corners RenderedBoards::corners_;

TEST_F(RenderedBoards, StereoRecoversFocalLengthsAndBaseline) {
  ASSERT_GE(corners_.left.size(), 12u);
  const double b_true = glm::length(rig_.X_RightEyeLeftEye.translation_m);
  const StereoCalibration s =
      calibrate_stereo(corners_.left, corners_.right, board_, {640, 480}, {640, 480});
  const double rot_err_deg =
      rotation_angle_between_rad(s.X_RightEyeLeftEye.rotation, rig_.X_RightEyeLeftEye.rotation) *
      kDeg;
  std::printf(
      "[ measured ] stereo, %zu views: RMS %.3f px; left fx %+.3f %% fy %+.3f %% cx %+.2f cy %+.2f "
      "px; right fx %+.3f %% fy %+.3f %% cx %+.2f cy %+.2f px; baseline %+.3f %% (%.2f mm); "
      "rotation off %.3f deg; t off %.2f mm\n",
      corners_.left.size(), s.rms_px, percent(s.left.model.k.fx, rig_.left.k.fx),
      percent(s.left.model.k.fy, rig_.left.k.fy), s.left.model.k.cx - rig_.left.k.cx,
      s.left.model.k.cy - rig_.left.k.cy, percent(s.right.model.k.fx, rig_.right.k.fx),
      percent(s.right.model.k.fy, rig_.right.k.fy), s.right.model.k.cx - rig_.right.k.cx,
      s.right.model.k.cy - rig_.right.k.cy, percent(s.baseline_m(), b_true), s.baseline_m() * 1e3,
      rot_err_deg,
      glm::length(s.X_RightEyeLeftEye.translation_m - rig_.X_RightEyeLeftEye.translation_m) * 1e3);
  EXPECT_LT(s.rms_px, 0.5);
  EXPECT_LT(std::abs(percent(s.left.model.k.fx, rig_.left.k.fx)), 1.0);
  EXPECT_LT(std::abs(percent(s.left.model.k.fy, rig_.left.k.fy)), 1.0);
  EXPECT_LT(std::abs(percent(s.right.model.k.fx, rig_.right.k.fx)), 1.0);
  EXPECT_LT(std::abs(percent(s.right.model.k.fy, rig_.right.k.fy)), 1.0);
  EXPECT_LT(std::abs(percent(s.baseline_m(), b_true)), 1.0);
  EXPECT_LT(std::abs(s.left.model.k.cx - rig_.left.k.cx), 2.0);
  EXPECT_LT(std::abs(s.right.model.k.cy - rig_.right.k.cy), 2.0);
  EXPECT_LT(rot_err_deg, 0.2);
  // The rig's convention: p_right = R p_left + t, the left eye to the left: t.x ~ -baseline.
  EXPECT_LT(s.X_RightEyeLeftEye.translation_m.x, -0.06);
  EXPECT_NEAR(s.left.model.distortion[0], rig_.left.distortion[0], 0.02);
  EXPECT_EQ(s.left.model.distortion[4], 0.0) << "k3 held at 0 by default";
  ASSERT_EQ(s.view_rms_px.size(), corners_.left.size());
  EXPECT_EQ(s.left.model.k.width, 640);

  // Each eye's own intrinsics held (no joint refinement): also within the bounds.
  CalibrateOptions held;
  held.joint_refine = false;
  const StereoCalibration h =
      calibrate_stereo(corners_.left, corners_.right, board_, {640, 480}, {640, 480}, held);
  std::printf(
      "[ measured ] stereo with each eye's own intrinsics held: RMS %.3f px, left fx %+.3f %%, "
      "right fx %+.3f %%, baseline %+.3f %%\n",
      h.rms_px, percent(h.left.model.k.fx, rig_.left.k.fx),
      percent(h.right.model.k.fx, rig_.right.k.fx), percent(h.baseline_m(), b_true));
  EXPECT_LT(h.left.rms_px, 0.5);
  EXPECT_LT(h.right.rms_px, 0.5);
  EXPECT_LT(std::abs(percent(h.left.model.k.fx, rig_.left.k.fx)), 1.0);
  EXPECT_LT(std::abs(percent(h.right.model.k.fx, rig_.right.k.fx)), 1.0);
  EXPECT_LT(std::abs(percent(h.baseline_m(), b_true)), 1.0);
}

TEST_F(RenderedBoards, DepthEyeRecoversThePose) {
  ASSERT_GE(corners_.ir.size(), 12u);
  // The right eye as calibrated (the lab's chain), not the truth.
  const StereoCalibration s =
      calibrate_stereo(corners_.left, corners_.right, board_, {640, 480}, {640, 480});
  const DepthEyeCalibration d = calibrate_depth_eye(corners_.ir, corners_.right, board_,
                                                    rig_.depth.k, s.right.model, corners_.depth);
  const double t_err_mm =
      glm::length(d.X_RightEyeDepth.translation_m - rig_.X_RightEyeDepth.translation_m) * 1e3;
  const double r_err_deg =
      rotation_angle_between_rad(d.X_RightEyeDepth.rotation, rig_.X_RightEyeDepth.rotation) * kDeg;
  std::printf(
      "[ measured ] depth-eye, %zu views: translation off %.3f mm, rotation off %.4f deg, "
      "residual %.3f mm, reprojection RMS %.3f px\n",
      corners_.ir.size(), t_err_mm, r_err_deg, d.residual_mm, d.rms_px);
  EXPECT_LT(t_err_mm, 2.0);
  EXPECT_LT(r_err_deg, 0.2);
  EXPECT_LT(d.residual_mm, 1.0);
  EXPECT_LT(d.rms_px, 0.5);
  ASSERT_EQ(d.view_residual_mm.size(), corners_.ir.size());

  // The depth maps: the board plane where the IR pose puts it, and the plane-only estimate.
  ASSERT_EQ(d.planes.size(), corners_.ir.size());
  double worst_offset = 0.0, worst_angle = 0.0;
  for (const DepthPlaneView& p : d.planes) {
    ASSERT_TRUE(p.used);
    worst_offset = std::max(worst_offset, std::abs(p.offset_to_ir_plane_mm));
    worst_angle = std::max(worst_angle, p.angle_to_ir_plane_deg);
  }
  ASSERT_TRUE(d.X_RightEyeDepth_from_planes);
  const double tp_err_mm = glm::length(d.X_RightEyeDepth_from_planes->translation_m -
                                       rig_.X_RightEyeDepth.translation_m) *
                           1e3;
  const double rp_err_deg = rotation_angle_between_rad(d.X_RightEyeDepth_from_planes->rotation,
                                                       rig_.X_RightEyeDepth.rotation) *
                            kDeg;
  std::printf(
      "[ measured ] depth planes: worst offset to the IR plane %.3f mm, worst angle %.3f deg; "
      "from planes alone: translation off %.3f mm, rotation off %.4f deg\n",
      worst_offset, worst_angle, tp_err_mm, rp_err_deg);
  EXPECT_LT(worst_offset, 1.0);
  EXPECT_LT(worst_angle, 0.3);
  EXPECT_LT(tp_err_mm, 3.0);
  EXPECT_LT(rp_err_deg, 0.3);

  // With the true right eye the method itself is exact to the corner noise: what is left above
  // comes from the eye's calibration.
  const DepthEyeCalibration e =
      calibrate_depth_eye(corners_.ir, corners_.right, board_, rig_.depth.k, rig_.right);
  const double te_mm =
      glm::length(e.X_RightEyeDepth.translation_m - rig_.X_RightEyeDepth.translation_m) * 1e3;
  const double re_deg =
      rotation_angle_between_rad(e.X_RightEyeDepth.rotation, rig_.X_RightEyeDepth.rotation) * kDeg;
  std::printf(
      "[ measured ] depth-eye with the true right eye: translation off %.3f mm, rotation off "
      "%.4f deg\n",
      te_mm, re_deg);
  EXPECT_LT(te_mm, 0.5);
  EXPECT_LT(re_deg, 0.05);
  EXPECT_TRUE(e.planes.empty());
  EXPECT_FALSE(e.X_RightEyeDepth_from_planes);
}

}  // namespace
}  // namespace telex::calib
