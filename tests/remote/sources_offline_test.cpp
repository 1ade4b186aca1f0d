// SPDX-License-Identifier: MIT
// Hardware-free sources: the real desk frames through `files:`, synthetic depth and stereo views.
#include <gtest/gtest.h>

#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "process.h"
#include "telex/common/depth_io.h"
#include "telex/common/synthetic.h"
#include "telex/remote/sources.h"
#include "telex/remote/synthetic_view.h"
#include "telex/video/frame_counter.h"
#include "test_support.h"

namespace telex::remote {
namespace {

using namespace std::chrono_literals;

TEST(FilesSource, DeliversTheRealDeskFramesInOrderThenEnds) {
  TELEX_REQUIRE_REAL_DATA();
  const auto dir = test::real_data_dir() / "desk";
  auto source =
      make_depth_source("files:" + (dir / "desk_*_depth_mm.png").string() + ",units=mm,fps=200");
  source->start();
  EXPECT_EQ(source->frame_count(), 3);
  for (int i = 0; i < 3; ++i) {
    auto r = source->read(1000ms);
    ASSERT_EQ(r.status, ReadStatus::Frame) << r.error;
    const auto truth = cv::imread((dir / ("desk_" + std::to_string(i) + "_depth_mm.png")).string(),
                                  cv::IMREAD_UNCHANGED);
    ASSERT_EQ(truth.type(), CV_16UC1);
    EXPECT_EQ(cv::norm(r.frame.image.depth_mm, truth, cv::NORM_INF), 0.0) << "frame " << i;
    EXPECT_EQ(r.frame.frame_id, static_cast<std::uint64_t>(i + 1));
  }
  EXPECT_EQ(source->read(100ms).status, ReadStatus::EndOfStream);
}

TEST(FilesSource, LoopsAndNamesBadPatternsAndUnits) {
  const auto dir = ::telex::test::scratch_dir("files");
  std::filesystem::create_directories(dir);
  cv::Mat1w a(4, 6, std::uint16_t(1000)), b(4, 6, std::uint16_t(2000));
  save_depth_png(dir / "f0.png", a);
  save_depth_png(dir / "f1.png", b);
  auto source = make_depth_source("files:" + (dir / "f*.png").string() + ",loop,fps=500");
  source->start();
  std::vector<std::uint16_t> seen;
  for (int i = 0; i < 5; ++i) {
    auto r = source->read(500ms);
    ASSERT_EQ(r.status, ReadStatus::Frame) << r.error;
    seen.push_back(r.frame.image.depth_mm(0, 0));
    // Each frame is the reader's own: writing into it changes no later pass.
    r.frame.image.depth_mm.setTo(7);
    // A looping replay decodes each file once: the later passes read no file.
    if (i == 1) {
      std::filesystem::remove(dir / "f0.png");
      std::filesystem::remove(dir / "f1.png");
    }
  }
  EXPECT_EQ(seen, (std::vector<std::uint16_t>{1000, 2000, 1000, 2000, 1000}));

  auto none = make_depth_source("files:" + (dir / "nothing*.png").string());
  try {
    none->start();
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("nothing*.png"), std::string::npos);
  }
  EXPECT_THROW(make_depth_source("files:x*.png,units=inches"), std::invalid_argument);
  EXPECT_THROW(make_depth_source("files:x*.png,fps=-3"), std::invalid_argument);
  std::filesystem::remove_all(dir);
}

TEST(SyntheticSource, PlaneSceneMatchesGroundTruthWithinSensorNoise) {
  SourceOptions opt;
  opt.synthetic_fps = 500;
  auto source = make_depth_source("synthetic:plane", opt);
  source->start();
  const auto r = source->read(1000ms);
  ASSERT_EQ(r.status, ReadStatus::Frame);
  // The "plane" wall stands at 0.8 m facing the camera: sigma_z there is about 1.5 mm plus ~2 mm
  // quantisation, so the median valid depth is within a few mm of 800.
  cv::Mat1w d = r.frame.image.depth_mm;
  std::vector<std::uint16_t> valid;
  for (auto v : d)
    if (v) valid.push_back(v);
  ASSERT_GT(valid.size(), d.total() * 9 / 10);
  std::nth_element(valid.begin(), valid.begin() + valid.size() / 2, valid.end());
  EXPECT_NEAR(valid[valid.size() / 2], 800, 4);
  // Noise varies per frame even on a static scene.
  const auto r2 = source->read(1000ms);
  ASSERT_EQ(r2.status, ReadStatus::Frame);
  EXPECT_GT(cv::norm(r.frame.image.depth_mm, r2.frame.image.depth_mm, cv::NORM_L1), 0.0);
  EXPECT_THROW(make_depth_source("synthetic:nowhere"), std::invalid_argument);
  EXPECT_THROW(make_depth_source("synthetic:plane,noise=maybe"), std::invalid_argument);
}

TEST(SyntheticSource, MovingSceneAnimatesAndNoiseOffIsDeterministic) {
  SourceOptions opt;
  opt.synthetic_fps = 500;
  opt.width = 160;
  opt.height = 120;
  auto a = make_depth_source("synthetic:moving,noise=off", opt);
  auto b = make_depth_source("synthetic:moving,noise=off", opt);
  a->start();
  b->start();
  const auto a0 = a->read(1000ms), a1 = a->read(1000ms);
  const auto b0 = b->read(1000ms);
  ASSERT_EQ(a0.status, ReadStatus::Frame);
  ASSERT_EQ(a1.status, ReadStatus::Frame);
  EXPECT_EQ(cv::norm(a0.frame.image.depth_mm, b0.frame.image.depth_mm, cv::NORM_INF), 0.0);
  EXPECT_GT(a1.frame.scene_time_s, a0.frame.scene_time_s);
  EXPECT_GT(cv::norm(a0.frame.image.depth_mm, a1.frame.image.depth_mm, cv::NORM_L1),
            0.0);  // the sphere moved
}

TEST(SyntheticStereo, EyesSeeTheSceneFromTheirOwnPositions) {
  SourceOptions opt;
  opt.synthetic_fps = 500;
  opt.width = 160;
  opt.height = 120;
  auto source = make_stereo_source("synthetic:sphere", opt);
  source->start();
  const auto r = source->read(1000ms);
  ASSERT_EQ(r.status, ReadStatus::Frame);
  ASSERT_EQ(r.frame.left_bgr.size(), cv::Size(160, 120));
  // The frame counter's corner aside (SyntheticStereo.EyesCarryTheirFrameId)...
  const cv::Rect counter = video::frame_counter_rect(r.frame.left_bgr.size());
  ASSERT_FALSE(counter.empty());
  cv::Mat3b left = r.frame.left_bgr.clone(), right = r.frame.right_bgr.clone();
  left(counter).setTo(cv::Vec3b(0, 0, 0));
  right(counter).setTo(cv::Vec3b(0, 0, 0));
  // ...the right eye = depth camera: its shading is lit wherever the ground truth has a surface.
  const auto scene = synth::Scene::named("sphere");
  const auto truth =
      synth::render(scene, kinect_v1_intrinsics(160, 120), synth::SensorModel::ideal());
  cv::Mat3b expected = shade_render(truth, scene, kinect_v1_intrinsics(160, 120), glm::dvec3(0.0));
  expected(counter).setTo(cv::Vec3b(0, 0, 0));
  EXPECT_EQ(cv::norm(right, expected, cv::NORM_INF), 0.0);
  // The left eye sits 65 mm to the left, so the near sphere shifts right by f*b/z ~ 13 px at 0.55
  // m.
  EXPECT_GT(cv::norm(left, right, cv::NORM_L1), 0.0);
  cv::Mat gl, gr;
  cv::extractChannel(left, gl, 1);
  cv::extractChannel(right, gr, 1);
  const cv::Moments ml = cv::moments(gl > 100, true), mr = cv::moments(gr > 100, true);
  ASSERT_GT(ml.m00, 0);
  ASSERT_GT(mr.m00, 0);
  EXPECT_GT(ml.m10 / ml.m00, mr.m10 / mr.m00);
}

// Glass to glass: each pair carries its frame id in both eyes' pixels.
TEST(SyntheticStereo, EyesCarryTheirFrameId) {
  SourceOptions opt;
  opt.synthetic_fps = 500;
  opt.width = 320;
  opt.height = 240;
  auto source = make_stereo_source("synthetic:moving", opt);
  source->start();
  for (int i = 0; i < 3; ++i) {
    const auto r = source->read(1000ms);
    ASSERT_EQ(r.status, ReadStatus::Frame);
    const auto id = static_cast<std::uint32_t>(r.frame.frame_id);
    EXPECT_EQ(video::read_frame_counter(r.frame.left_bgr), id);
    EXPECT_EQ(video::read_frame_counter(r.frame.right_bgr), id);
  }
}

// A looping stereo replay decodes each pair once: the second time round it hands over the kept
// pair (the files are gone by then), each time a copy of its own.
TEST(FilesStereo, ALoopingReplayDecodesEachPairOnceAndHandsOverCopies) {
  const auto dir = ::telex::test::scratch_dir("files_stereo");
  std::vector<cv::Mat3b> left, right;
  for (int i = 0; i < 2; ++i) {
    left.emplace_back(48, 64, cv::Vec3b(10 + 40 * i, 20, 30));
    right.emplace_back(48, 64, cv::Vec3b(200, 20 + 40 * i, 30));
    ASSERT_TRUE(cv::imwrite((dir / ("l" + std::to_string(i) + ".png")).string(), left.back()));
    ASSERT_TRUE(cv::imwrite((dir / ("r" + std::to_string(i) + ".png")).string(), right.back()));
  }
  auto source = make_stereo_source("files:" + (dir / "l*.png").string() + "," +
                                   (dir / "r*.png").string() + ",fps=500,loop");
  source->start();
  for (int i = 0; i < 2; ++i) {
    auto r = source->read(1000ms);
    ASSERT_EQ(r.status, ReadStatus::Frame) << r.error;
    EXPECT_EQ(cv::norm(r.frame.left_bgr, left[i], cv::NORM_INF), 0.0);
    r.frame.left_bgr.setTo(cv::Scalar(0, 0, 0));  // the pipeline works in place
  }
  std::filesystem::remove_all(dir);
  for (int round = 0; round < 2; ++round)
    for (int i = 0; i < 2; ++i) {
      auto r = source->read(1000ms);
      ASSERT_EQ(r.status, ReadStatus::Frame)
          << "round " << round << " pair " << i << ": " << r.error;
      EXPECT_EQ(cv::norm(r.frame.left_bgr, left[i], cv::NORM_INF), 0.0);
      EXPECT_EQ(cv::norm(r.frame.right_bgr, right[i], cv::NORM_INF), 0.0);
      r.frame.right_bgr.setTo(cv::Scalar(0, 0, 0));
    }
}

TEST(FilesStereo, MissingImagesAreNamed) {
  EXPECT_THROW(make_stereo_source("files:/only/left*.png"), std::invalid_argument);
  auto s = make_stereo_source("files:/nope/l*.png,/nope/r*.png");
  try {
    s->start();
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nope/l*.png"), std::string::npos);
  }
}

}  // namespace
}  // namespace telex::remote
