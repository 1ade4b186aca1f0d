// SPDX-License-Identifier: MIT
// Tile selection, key frames and ROI rates of the remote pipeline, without a network.
#include "telex/remote/pipeline.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

#include "depth_error.h"
#include "flags.h"
#include "remote_frames.h"
#include "telex/common/synthetic.h"

namespace telex::remote {
namespace {

using test::frame_of;

PipelineConfig no_fill_config() {
  PipelineConfig c;
  c.fill = false;
  c.key_frame_every = 10;
  return c;
}

TEST(FramePipeline, KeyFrameFirstThenOnlyChangedTiles) {
  FramePipeline p(no_fill_config());
  cv::Mat1w d(480, 640, std::uint16_t(1500));
  auto f1 = p.process(frame_of(d, 1), {});
  EXPECT_TRUE(f1.key_frame);
  EXPECT_EQ(f1.tiles.size(), 64u);
  EXPECT_TRUE(f1.manifest.key_frame);
  auto f2 = p.process(frame_of(d, 2), {});
  EXPECT_FALSE(f2.key_frame);
  EXPECT_TRUE(f2.tiles.empty());
  EXPECT_EQ(f2.tiles_skipped, 64u);
  d(130, 170) = 1600;  // tile column 2, row 2 -> index 18
  auto f3 = p.process(frame_of(d, 3), {});
  ASSERT_EQ(f3.tiles.size(), 1u);
  EXPECT_EQ(f3.tiles[0].index, 18);
  EXPECT_EQ(f3.manifest.changed_tiles, std::vector<std::uint16_t>{18});
  EXPECT_EQ(cv::norm(f3.sent_view_mm, d, cv::NORM_INF), 0.0);
  // Each tile decodes alone to the sender's pixels.
  cv::Mat1w tile;
  ASSERT_EQ(proto::decode_depth(f3.tiles[0].bytes, 80, 60, f3.codec, tile),
            proto::DecodeStatus::Ok);
  EXPECT_EQ(cv::norm(tile, d(f3.tiles[0].rect), cv::NORM_INF), 0.0);
}

TEST(FramePipeline, PeriodicAndRequestedKeyFrames) {
  FramePipeline p(no_fill_config());
  cv::Mat1w d(120, 160, std::uint16_t(900));
  std::vector<int> keys;
  for (int i = 1; i <= 25; ++i) {
    FrameRequest r;
    r.force_key_frame = i == 14;
    if (p.process(frame_of(d, static_cast<std::uint64_t>(i)), r).key_frame) keys.push_back(i);
  }
  EXPECT_EQ(keys, (std::vector<int>{1, 11, 14, 24}));
}

TEST(FramePipeline, RoiTilesAtFullRateOthersAtTheBackgroundRate) {
  PipelineConfig c = no_fill_config();
  c.key_frame_every = 1000;
  c.background_every = 3;
  FramePipeline p(c);
  cv::Mat1w d(480, 640, std::uint16_t(1000));
  p.process(frame_of(d, 1), {});
  FrameRequest r;
  r.rois = {proto::RoiRect{0, 0, 80, 60, 1}};  // tile 0 only
  std::vector<std::size_t> sent;
  for (int i = 2; i <= 7; ++i) {
    d += 10;  // every tile changes every frame
    sent.push_back(p.process(frame_of(d, static_cast<std::uint64_t>(i)), r).tiles.size());
  }
  // Frames 3 and 6 are background frames (counter % 3 == 0): all 64 tiles; otherwise the ROI tile.
  EXPECT_EQ(sent, (std::vector<std::size_t>{1, 64, 1, 1, 64, 1}));
}

TEST(FramePipeline, FillClosesSensorHolesOnTheTrueSurface) {
  // "tilted": one plane at 35 deg, so every hole (dropout, grazing) has only that surface around
  // it.
  auto rendered =
      synth::render(synth::Scene::named("tilted"), kinect_v1_intrinsics(), synth::SensorModel{}, 0);
  FramePipeline p(PipelineConfig{});
  auto out = p.process(frame_of(rendered.depth.depth_mm, 1), {});
  ASSERT_GT(out.holes_in, 300u);
  EXPECT_LT(out.holes_out, out.holes_in / 10);
  int near = 0, total = 0;
  for (int y = 0; y < 480; ++y)
    for (int x = 0; x < 640; ++x)
      if (rendered.depth.depth_mm(y, x) == 0 && out.sent_view_mm(y, x) != 0 &&
          rendered.true_depth_m(y, x) > 0) {
        ++total;
        // 3 sigma of the sensor at <= 1.4 m plus one 20 mm fill bin.
        if (std::abs(out.sent_view_mm(y, x) - rendered.true_depth_m(y, x) * 1000.0) < 30.0) ++near;
      }
  ASSERT_GT(total, 300);
  EXPECT_GT(static_cast<double>(near) / total, 0.99);
}

TEST(FramePipeline, FillLeavesFewHolesOnStepEdges) {
  // At the box's step edges the projector shadow is filled from whichever surface dominates the
  // window, so only the count of holes is checked here, not their depth.
  auto rendered =
      synth::render(synth::Scene::named("box"), kinect_v1_intrinsics(), synth::SensorModel{}, 0);
  FramePipeline p(PipelineConfig{});
  auto out = p.process(frame_of(rendered.depth.depth_mm, 1), {});
  EXPECT_GT(out.holes_in, 1000u);
  EXPECT_LT(out.holes_out, out.holes_in / 10);
}

}  // namespace
}  // namespace telex::remote

namespace telex::remote {
namespace {

// Registration stage: the scene rendered from the depth camera goes through the pipeline and is
// compared with the same scene rendered from the right-eye camera (bounds as in
// tests/common/registration_test.cpp).
const Intrinsics kEyeK{580.0, 580.0, 322.0, 236.0, 640, 480};
const glm::dvec3 kEyeCentre_m(0.025, 0.0, 0.0);

PipelineConfig registering(RegisterMode mode, double nominal_m = 1.0) {
  PipelineConfig c;
  c.registration = parse_registration(register_mode_name(mode), "0.025,0,0", "0,0,0",
                                      "580,580,322,236,640,480", nominal_m);
  c.fill = false;  // compare the registration itself, not the fill
  c.codec = proto::Codec::Zip;
  return c;
}

// What a receiver holds after one key frame of `scene` through a pipeline with `config`.
ProcessedFrame through_pipeline(const synth::Scene& scene, const PipelineConfig& config) {
  const synth::Rendered from_depth =
      synth::render(scene, kinect_v1_intrinsics(), synth::SensorModel::ideal());
  DepthFrame f;
  f.image = from_depth.depth;
  f.frame_id = 1;
  FramePipeline p(config);
  FrameRequest req;
  req.force_key_frame = true;
  return p.process(f, req);
}

class PipelineRegistrationScene : public ::testing::TestWithParam<const char*> {};

TEST_P(PipelineRegistrationScene, FullMatchesTheSceneSeenFromTheEye) {
  const char* name = GetParam();
  const synth::Scene scene = synth::Scene::named(name);
  const ProcessedFrame out = through_pipeline(scene, registering(RegisterMode::Full));
  const synth::Rendered truth =
      synth::render_from(scene, kEyeK, kEyeCentre_m, synth::SensorModel::ideal());
  EXPECT_EQ(out.intrinsics, kEyeK);
  ASSERT_EQ(out.sent_view_mm.size(), truth.true_depth_m.size());
  EXPECT_EQ(out.grid.frame_width, 640);
  const test::DepthError e = test::compare_depth(out.sent_view_mm, truth.true_depth_m);
  std::printf("[ pipeline full ] %-7s median %.2f mm, p90 %.2f mm, coverage %.3f\n", name,
              e.median_mm, e.p90_mm, e.coverage);
  EXPECT_LT(e.median_mm, 2.0);
  EXPECT_GT(e.coverage, 0.97);
  // Unregistered, the same frame has its edges where the depth camera saw them: many more
  // pixels misplaced by more than 10 mm. The stage did the work.
  const ProcessedFrame raw = through_pipeline(scene, registering(RegisterMode::None));
  EXPECT_EQ(raw.intrinsics, kinect_v1_intrinsics());
  const test::DepthError unregistered = test::compare_depth(raw.sent_view_mm, truth.true_depth_m);
  std::printf("[ pipeline none ] %-7s >10 mm %.2f %% (registered %.2f %%)\n", name,
              100 * unregistered.over_10mm, 100 * e.over_10mm);
  EXPECT_GT(unregistered.over_10mm, 2.0 * e.over_10mm + 0.005);
}

INSTANTIATE_TEST_SUITE_P(Scenes, PipelineRegistrationScene,
                         ::testing::Values("desk", "box", "sphere", "tilted", "stairs"),
                         [](const auto& info) { return std::string(info.param); });

TEST(PipelineRegistration, ShiftIsExactAtItsNominalDepthOnly) {
  // A fronto-parallel plane at the nominal depth: shift+scale is exact there.
  synth::Scene at_nominal;
  at_nominal.add_plane({0, 0, 1}, 1.2);
  const synth::Rendered truth =
      synth::render_from(at_nominal, kEyeK, kEyeCentre_m, synth::SensorModel::ideal());
  const test::DepthError exact = test::compare_depth(
      through_pipeline(at_nominal, registering(RegisterMode::Shift, 1.2)).sent_view_mm,
      truth.true_depth_m);
  EXPECT_LT(exact.median_mm, 1.0);
  EXPECT_GT(exact.coverage, 0.95);
  // On the desk (depths 0.7..2 m) derived for 0.8 m it misplaces what is far from 0.8 m: a worse
  // p90 than full reprojection, as in the common registration tests.
  const synth::Scene desk = synth::Scene::named("desk");
  const synth::Rendered desk_truth =
      synth::render_from(desk, kEyeK, kEyeCentre_m, synth::SensorModel::ideal());
  const test::DepthError shift = test::compare_depth(
      through_pipeline(desk, registering(RegisterMode::Shift, 0.8)).sent_view_mm,
      desk_truth.true_depth_m);
  const test::DepthError full =
      test::compare_depth(through_pipeline(desk, registering(RegisterMode::Full)).sent_view_mm,
                          desk_truth.true_depth_m);
  std::printf("[ pipeline desk ] shift@0.8 p90 %.2f mm, full p90 %.2f mm\n", shift.p90_mm,
              full.p90_mm);
  EXPECT_GT(shift.p90_mm, full.p90_mm);
  EXPECT_LT(full.median_mm, 2.0);
}

TEST(PipelineRegistration, NoneIsBitExactAndBadSettingsAreNamed) {
  cv::Mat1w depth(48, 64);
  cv::randu(depth, 0, 4000);
  PipelineConfig c;
  c.fill = false;
  FramePipeline p(c);
  FrameRequest req;
  req.force_key_frame = true;
  const ProcessedFrame out = p.process(frame_of(depth, 1), req);
  EXPECT_EQ(cv::norm(out.sent_view_mm, depth, cv::NORM_INF), 0.0);
  EXPECT_GE(out.times.register_ms, 0.0);

  EXPECT_THROW(parse_register_mode("affine"), std::invalid_argument);
  try {
    parse_registration("full", "0.025,0", "0,0,0", "", 1.0);
    FAIL() << "two-number baseline accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("--register-baseline"), std::string::npos) << e.what();
  }
  EXPECT_THROW(parse_registration("full", "0.025,0,x", "0,0,0", "", 1.0), std::invalid_argument);
  EXPECT_THROW(parse_registration("full", "0,0,0", "0,0", "", 1.0), std::invalid_argument);
  EXPECT_THROW(parse_registration("full", "0,0,0", "0,0,0", "580,580,322,236,640", 1.0),
               std::invalid_argument);
  EXPECT_THROW(parse_registration("full", "0,0,0", "0,0,0", "-1,580,322,236,640,480", 1.0),
               std::invalid_argument);
  EXPECT_THROW(parse_registration("shift", "0,0,0", "0,0,0", "", 0.0), std::invalid_argument);
}

TEST(PipelineRegistration, ExtrinsicsFollowTheDocumentedConvention) {
  // Eye 2.5 cm to the right: a depth-frame point is 2.5 cm to the left in the eye's frame.
  const RegistrationConfig r = parse_registration("full", "0.025,0,0", "0,0,0", "", 1.0);
  EXPECT_NEAR(r.X_EyeDepth.translation_m.x, -0.025, 1e-12);
  EXPECT_EQ(r.eye.width, 0);  // the source's own intrinsics
  // Eye turned 90 degrees about y (looking along the depth camera's +x): a point 1 m along +x
  // is 1 m in front of it.
  const RegistrationConfig t = parse_registration("full", "0,0,0", "0,90,0", "", 1.0);
  const glm::dvec3 p = t.X_EyeDepth.rotation * glm::dvec3(1, 0, 0) + t.X_EyeDepth.translation_m;
  EXPECT_NEAR(p.x, 0.0, 1e-12);
  EXPECT_NEAR(p.y, 0.0, 1e-12);
  EXPECT_NEAR(p.z, 1.0, 1e-12);
}

}  // namespace
}  // namespace telex::remote
