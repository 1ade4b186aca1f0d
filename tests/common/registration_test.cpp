// SPDX-License-Identifier: MIT
// Registration tests: synthetic scenes rendered from both viewpoints give the ground truth.
#include "telex/common/registration.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>

#include "depth_error.h"
#include "telex/common/synthetic.h"

namespace telex {
namespace {

// The right-eye camera: narrower field of view, its own principal point, 2.5 cm to the right.
const Intrinsics kDepthK = kinect_v1_intrinsics();
const Intrinsics kEyeK{580.0, 580.0, 322.0, 236.0, 640, 480};
const glm::dvec3 kEyeCentre_m(0.025, 0.0, 0.0);

RigidTransform X_EyeDepth() {
  RigidTransform x;
  x.translation_m = -kEyeCentre_m;
  return x;
}

TEST(Registration, ShiftScaleFromCalibration) {
  const ShiftScale p = shift_scale_from_calibration(kDepthK, kEyeK, -kEyeCentre_m, 1.0);
  EXPECT_DOUBLE_EQ(p.scale_x, 580.0 / 525.0);
  EXPECT_DOUBLE_EQ(p.scale_y, 580.0 / 525.0);
  EXPECT_DOUBLE_EQ(p.shift_x_px, -580.0 * 0.025);
  EXPECT_DOUBLE_EQ(p.shift_y_px, 0.0);
  EXPECT_EQ(p.depth_offset_mm, 0);
  EXPECT_THROW(shift_scale_from_calibration(kDepthK, kEyeK, {}, 0.0), std::invalid_argument);
}

TEST(Registration, ShiftScaleMagnifiesWithoutCracksAndNearestWins) {
  DepthImage d;
  d.intrinsics = kinect_v1_intrinsics(40, 30);
  d.depth_mm = cv::Mat1w(30, 40, std::uint16_t{1500});
  ShiftScale up;
  up.scale_x = up.scale_y = 2.0;
  const Intrinsics big = kinect_v1_intrinsics(80, 60);
  const DepthImage m = register_shift_scale(d, up, big);
  EXPECT_EQ(cv::countNonZero(m.depth_mm == 1500), 80 * 60);  // every pixel covered

  // Halving: each target pixel sees two source columns; the nearer must win.
  for (int u = 0; u < 40; u += 2) d.depth_mm.col(u).setTo(900);
  ShiftScale down;
  down.scale_x = down.scale_y = 0.5;
  const DepthImage s = register_shift_scale(d, down, kinect_v1_intrinsics(20, 15));
  EXPECT_EQ(cv::countNonZero(s.depth_mm == 900), 20 * 15);

  // Holes write nothing.
  d.depth_mm.setTo(0);
  const DepthImage h = register_shift_scale(d, up, big);
  EXPECT_EQ(cv::countNonZero(h.depth_mm), 0);
}

TEST(Registration, ReprojectIdentityIsExact) {
  const synth::Rendered r =
      synth::render(synth::Scene::named("desk"), kDepthK, synth::SensorModel{});
  const DepthImage same = reproject_depth(r.depth, kDepthK, RigidTransform{}, false);
  EXPECT_EQ(cv::norm(same.depth_mm, r.depth.depth_mm, cv::NORM_INF), 0.0);
}

TEST(Registration, RejectsBadInput) {
  DepthImage empty;
  EXPECT_THROW(reproject_depth(empty, kEyeK, RigidTransform{}), std::invalid_argument);
  EXPECT_THROW(register_shift_scale(empty, ShiftScale{}, kEyeK), std::invalid_argument);
}

// Full reprojection against the scene rendered from the eye itself (ideal sensor).
class RegistrationScene : public ::testing::TestWithParam<const char*> {};

TEST_P(RegistrationScene, FullReprojectionMatchesSecondViewpoint) {
  const char* name = GetParam();
  const synth::Scene scene = synth::Scene::named(name);
  const synth::Rendered from_depth = synth::render(scene, kDepthK, synth::SensorModel::ideal());
  const synth::Rendered truth =
      synth::render_from(scene, kEyeK, kEyeCentre_m, synth::SensorModel::ideal());
  for (bool fill : {false, true}) {
    const DepthImage reg = reproject_depth(from_depth.depth, kEyeK, X_EyeDepth(), fill);
    const test::DepthError e = test::compare_depth(reg.depth_mm, truth.true_depth_m);
    std::printf("[ reproject ] %-7s fill_cracks=%d median %.2f mm, p90 %.2f mm, coverage %.3f\n",
                name, fill, e.median_mm, e.p90_mm, e.coverage);
    EXPECT_LT(e.median_mm, 2.0);
    // Magnifying 580/525 opens cracks in about one column or row in ten; the splat closes them.
    EXPECT_GT(e.coverage, fill ? 0.97 : 0.75);
  }
}

// The stereo view's left eye: the same camera 6.5 cm to the side. Along the rows it is as true as
// the full reprojection, against the scene rendered from there, and mostly the same pixels.
TEST_P(RegistrationScene, AShiftAlongTheRowsMatchesTheFullReprojection) {
  const char* name = GetParam();
  const synth::Scene scene = synth::Scene::named(name);
  const synth::Rendered from_depth = synth::render(scene, kDepthK, synth::SensorModel::ideal());
  const glm::dvec3 left_m(-0.065, 0.0, 0.0);
  const synth::Rendered truth =
      synth::render_from(scene, kDepthK, left_m, synth::SensorModel::ideal());
  const RigidTransform X_LeftDepth{glm::dmat3(1.0), -left_m};
  const DepthImage full = reproject_depth(from_depth.depth, kDepthK, X_LeftDepth);
  cv::Mat1w rows(3, 3, std::uint16_t{7});  // another size: reallocated
  shift_depth_along_rows(from_depth.depth.depth_mm, kDepthK.fx, 0.065, rows);
  ASSERT_EQ(rows.size(), full.depth_mm.size());
  const test::DepthError e_full = test::compare_depth(full.depth_mm, truth.true_depth_m);
  const test::DepthError e_rows = test::compare_depth(rows, truth.true_depth_m);
  const double same = static_cast<double>(cv::countNonZero(rows == full.depth_mm)) /
                      static_cast<double>(rows.total());
  std::printf("[ rows ] %-7s median %.2f mm (full %.2f), coverage %.4f (full %.4f), same %.4f\n",
              name, e_rows.median_mm, e_full.median_mm, e_rows.coverage, e_full.coverage, same);
  EXPECT_LE(e_rows.median_mm, e_full.median_mm + 0.5);
  EXPECT_LE(e_rows.p90_mm, e_full.p90_mm + 1.0);
  EXPECT_GE(e_rows.coverage, e_full.coverage - 0.002);
  EXPECT_GT(same, 0.99);
  EXPECT_THROW(shift_depth_along_rows(from_depth.depth.depth_mm, 0.0, 0.065, rows),
               std::invalid_argument);
}

INSTANTIATE_TEST_SUITE_P(Scenes, RegistrationScene,
                         ::testing::Values("desk", "box", "sphere", "tilted", "stairs"),
                         [](const auto& info) { return std::string(info.param); });

// Shift+scale is derived for 1.0 m. A pixel whose true depth is Z lands fx * b * |1/Z - 1/Z0| px
// off, which costs |dz/du| times that in depth: predicted per pixel from the ground truth.
TEST(Registration, ShiftScaleExactAtNominalDepthAndWorseAway) {
  const double nominal_m = 1.0, tilt = 35.0 * std::numbers::pi / 180.0;
  const ShiftScale p = shift_scale_from_calibration(kDepthK, kEyeK, -kEyeCentre_m, nominal_m);
  for (double z_m : {0.6, 1.0, 1.6, 2.5}) {
    synth::Scene scene;
    scene.add_plane({std::sin(tilt), 0, std::cos(tilt)}, std::cos(tilt) * z_m);
    const synth::Rendered from_depth = synth::render(scene, kDepthK, synth::SensorModel::ideal());
    const synth::Rendered truth =
        synth::render_from(scene, kEyeK, kEyeCentre_m, synth::SensorModel::ideal());
    const cv::Mat1w ss = register_shift_scale(from_depth.depth, p, kEyeK).depth_mm;
    const test::DepthError full = test::compare_depth(
        reproject_depth(from_depth.depth, kEyeK, X_EyeDepth()).depth_mm, truth.true_depth_m);
    std::vector<double> err, predicted, err_near_nominal;
    const cv::Mat1f& t = truth.true_depth_m;
    for (int v = 0; v < t.rows; ++v)
      for (int u = 1; u + 1 < t.cols; ++u) {
        if (ss(v, u) == 0) continue;
        const double e = std::abs(ss(v, u) - t(v, u) * 1000.0);
        const double slope_mm_per_px = (t(v, u + 1) - t(v, u - 1)) * 500.0;
        const double shift_px =
            kEyeK.fx * kEyeCentre_m.x * std::abs(1.0 / t(v, u) - 1.0 / nominal_m);
        err.push_back(e);
        predicted.push_back(std::abs(slope_mm_per_px) * shift_px);
        if (std::abs(t(v, u) - nominal_m) < 0.02) err_near_nominal.push_back(e);
      }
    auto median = [](std::vector<double> x) {
      if (x.empty()) return -1.0;
      std::nth_element(x.begin(), x.begin() + x.size() / 2, x.end());
      return x[x.size() / 2];
    };
    const double ss_med = median(err), pred_med = median(predicted);
    std::printf(
        "[ shift+scale @1.0 m ] plane through %.1f m: shift+scale median %.2f mm (predicted %.2f, "
        "%.2f within 2 cm of 1.0 m), full median %.2f mm\n",
        z_m, ss_med, pred_med, median(err_near_nominal), full.median_mm);
    EXPECT_LT(full.median_mm, 2.0);
    EXPECT_NEAR(ss_med, pred_med, 0.25 * pred_med + 0.5);
    if (!err_near_nominal.empty()) {
      EXPECT_LT(median(err_near_nominal), 1.0);
    }
    if (z_m != nominal_m) {
      EXPECT_GT(ss_med, 4.0 * full.median_mm);
    }
  }
}

TEST(Registration, DeskShiftScaleVersusFull) {
  const synth::Scene scene = synth::Scene::named("desk");
  const synth::Rendered from_depth = synth::render(scene, kDepthK, synth::SensorModel::ideal());
  const synth::Rendered truth =
      synth::render_from(scene, kEyeK, kEyeCentre_m, synth::SensorModel::ideal());
  const test::DepthError full = test::compare_depth(
      reproject_depth(from_depth.depth, kEyeK, X_EyeDepth()).depth_mm, truth.true_depth_m);
  for (double nominal_m : {0.8, 1.2, 2.0}) {
    const ShiftScale p = shift_scale_from_calibration(kDepthK, kEyeK, -kEyeCentre_m, nominal_m);
    const test::DepthError ss = test::compare_depth(
        register_shift_scale(from_depth.depth, p, kEyeK).depth_mm, truth.true_depth_m);
    std::printf(
        "[ desk ] shift+scale @%.1f m: median %.2f mm, p90 %.2f mm, >10 mm %.2f %%; "
        "full: median %.2f mm, p90 %.2f mm, >10 mm %.2f %%\n",
        nominal_m, ss.median_mm, ss.p90_mm, 100 * ss.over_10mm, full.median_mm, full.p90_mm,
        100 * full.over_10mm);
    EXPECT_GT(ss.p90_mm, full.p90_mm);
    EXPECT_GT(ss.over_10mm, full.over_10mm);
  }
  EXPECT_LT(full.median_mm, 2.0);
}

}  // namespace
}  // namespace telex
