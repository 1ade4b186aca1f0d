// SPDX-License-Identifier: MIT
// ROS 1 bags as a depth source: bags written here with the library itself (16UC1 and 32FC1 with
// CameraInfo, the real desk frames among them) read back exactly, paced by their stamps, looped,
// and every broken case named.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <opencv2/imgcodecs.hpp>

#include "process.h"
#include "telex/bag/bag.h"
#include "telex/remote/sources.h"
#include "test_support.h"

namespace telex::remote {
namespace {

using namespace std::chrono_literals;

constexpr std::int64_t kT0 = 1'700'000'000'000'000'000;  // a 2023 wall-clock stamp, ns
constexpr std::int64_t kPeriod = 33'333'333;

std::filesystem::path temp_bag(const std::string& name) {
  return ::telex::test::scratch_file(name);
}

bag::CameraIntrinsics k_of(int w, int h) {
  return {570.3, 571.1, w / 2.0 - 0.5, h / 2.0 + 1.5, w, h};
}

// Frames with every value a 16-bit depth can take somewhere in them (0 = hole, 65535).
std::vector<cv::Mat1w> ramp_frames(int n, int w, int h) {
  std::vector<cv::Mat1w> out;
  for (int i = 0; i < n; ++i) {
    cv::Mat1w f(h, w);
    for (int r = 0; r < h; ++r)
      for (int c = 0; c < w; ++c)
        f(r, c) = static_cast<std::uint16_t>((r * 7919 + c * 104729 + i * 31337) % 65536);
    f(0, 0) = 0;
    f(h - 1, w - 1) = 65535;
    out.push_back(f);
  }
  return out;
}

TEST(BagSource, SixteenBitFramesAndTheirIntrinsicsComeBackExactlyInOrderThenEnd) {
  const auto path = temp_bag("u16.bag");
  const auto frames = ramp_frames(5, 64, 48);
  {
    bag::Writer w(path.string());
    for (int i = 0; i < 5; ++i)
      w.depth_mm("/camera/depth/image_raw", "/camera/depth/camera_info", kT0 + i * kPeriod,
                 static_cast<std::uint32_t>(i), "camera", frames[static_cast<std::size_t>(i)],
                 k_of(64, 48));
  }
  auto source = make_depth_source("bag:" + path.string() + ",fast");
  source->start();
  EXPECT_EQ(source->frame_count(), 5);
  EXPECT_NEAR(source->nominal_fps(), 30.0, 1e-3);
  const Intrinsics k = source->intrinsics();
  EXPECT_EQ(k.fx, 570.3);
  EXPECT_EQ(k.fy, 571.1);
  EXPECT_EQ(k.cx, 31.5);
  EXPECT_EQ(k.cy, 25.5);
  EXPECT_EQ(k.width, 64);
  EXPECT_EQ(k.height, 48);
  EXPECT_NE(source->describe().find("/camera/depth/image_raw 16UC1, 5 frames"), std::string::npos)
      << source->describe();
  for (int i = 0; i < 5; ++i) {
    auto r = source->read(1000ms);
    ASSERT_EQ(r.status, ReadStatus::Frame) << r.error;
    EXPECT_EQ(cv::norm(r.frame.image.depth_mm, frames[static_cast<std::size_t>(i)], cv::NORM_INF),
              0.0)
        << "frame " << i;
    EXPECT_EQ(r.frame.frame_id, static_cast<std::uint64_t>(i + 1));
    EXPECT_NEAR(r.frame.scene_time_s, i * kPeriod * 1e-9, 1e-9);
    EXPECT_EQ(r.frame.image.intrinsics, k);
  }
  EXPECT_EQ(source->read(100ms).status, ReadStatus::EndOfStream);
}

TEST(BagSource, TheRealDeskFramesSurviveABagBitExact) {
  TELEX_REQUIRE_REAL_DATA();
  const auto dir = test::real_data_dir() / "desk";
  const auto path = temp_bag("desk.bag");
  std::vector<cv::Mat> truth;
  {
    bag::Writer w(path.string());
    for (int i = 0; i < 3; ++i) {
      truth.push_back(cv::imread((dir / ("desk_" + std::to_string(i) + "_depth_mm.png")).string(),
                                 cv::IMREAD_UNCHANGED));
      ASSERT_EQ(truth.back().type(), CV_16UC1);
      w.depth_mm("/desk/depth", "/desk/camera_info", kT0 + i * kPeriod,
                 static_cast<std::uint32_t>(i), "camera", truth.back(),
                 k_of(truth.back().cols, truth.back().rows));
    }
  }
  auto source = make_depth_source("bag:" + path.string() + ",fast");
  source->start();
  for (int i = 0; i < 3; ++i) {
    auto r = source->read(1000ms);
    ASSERT_EQ(r.status, ReadStatus::Frame) << r.error;
    EXPECT_EQ(cv::norm(r.frame.image.depth_mm, truth[static_cast<std::size_t>(i)], cv::NORM_INF),
              0.0)
        << "desk frame " << i;
  }
}

TEST(BagSource, MetreFramesBecomeMillimetresWithinHalfAMillimetreAndNanIsAHole) {
  const auto path = temp_bag("f32.bag");
  cv::Mat1f m(30, 40);
  for (int r = 0; r < m.rows; ++r)
    for (int c = 0; c < m.cols; ++c) m(r, c) = 0.4f + 0.00731f * static_cast<float>(r * 40 + c);
  m(1, 1) = std::numeric_limits<float>::quiet_NaN();
  m(2, 2) = std::numeric_limits<float>::infinity();
  m(3, 3) = -1.0f;
  m(4, 4) = 0.0f;
  m(5, 5) = 70.0f;  // beyond what millimetres in 16 bits hold
  {
    bag::Writer w(path.string());
    w.depth_m("/tum/depth", "/tum/camera_info", kT0, 0, "camera", m, k_of(40, 30));
  }
  auto source = make_depth_source("bag:" + path.string() + ",fast");
  source->start();
  auto r = source->read(1000ms);
  ASSERT_EQ(r.status, ReadStatus::Frame) << r.error;
  const cv::Mat1w& mm = r.frame.image.depth_mm;
  int holes = 0;
  for (int y = 0; y < m.rows; ++y)
    for (int x = 0; x < m.cols; ++x) {
      const float v = m(y, x);
      if (!(std::isfinite(v) && v > 0 && v < 65.0f)) {
        EXPECT_EQ(mm(y, x), 0) << y << "," << x;
        ++holes;
      } else {
        EXPECT_LE(std::abs(mm(y, x) - v * 1000.0), 0.5 + 1e-3) << y << "," << x;
      }
    }
  EXPECT_EQ(holes, 5);
}

TEST(BagSource, PlaysAtTheRecordedPaceByStampsOrScaledOrLooped) {
  const auto path = temp_bag("pace.bag");
  // Stamps 0, 100, 300 ms: uneven on purpose.
  const std::int64_t stamps[] = {0, 100'000'000, 300'000'000};
  {
    bag::Writer w(path.string());
    for (int i = 0; i < 3; ++i)
      w.depth_mm("/d", "/camera_info", kT0 + stamps[i], static_cast<std::uint32_t>(i), "camera",
                 cv::Mat1w(4, 4, static_cast<std::uint16_t>(1000 + i)), k_of(4, 4));
  }
  // The source's clock is the host's steady clock: what it delivers is checked through
  // capture_ns, which it stamps when a frame is due, and its scene time (the recorded stamps).
  auto paced = make_depth_source("bag:" + path.string() + ",rate=4");
  paced->start();
  std::vector<std::int64_t> captured;
  std::vector<double> scene;
  while (captured.size() < 3) {
    auto r = paced->read(500ms);
    if (r.status == ReadStatus::Timeout) continue;
    ASSERT_EQ(r.status, ReadStatus::Frame) << r.error;
    captured.push_back(r.frame.capture_ns);
    scene.push_back(r.frame.scene_time_s);
  }
  EXPECT_EQ(scene, (std::vector<double>{0.0, 0.1, 0.3}));
  // At 4x, frame n is not delivered before (stamp_n - stamp_0) / 4 after the first.
  EXPECT_GE(captured[1] - captured[0], 25'000'000);
  EXPECT_GE(captured[2] - captured[0], 75'000'000);

  auto looped = make_depth_source("bag:" + path.string() + ",loop,fast");
  looped->start();
  std::vector<std::uint16_t> values;
  std::vector<double> times;
  for (int i = 0; i < 7; ++i) {
    auto r = looped->read(500ms);
    ASSERT_EQ(r.status, ReadStatus::Frame) << r.error;
    values.push_back(r.frame.image.depth_mm(0, 0));
    times.push_back(r.frame.scene_time_s);
  }
  EXPECT_EQ(values, (std::vector<std::uint16_t>{1000, 1001, 1002, 1000, 1001, 1002, 1000}));
  // The second pass plays on one recorded period (200 ms, the last gap) after the last frame.
  EXPECT_NEAR(times[3], 0.5, 1e-9);
  EXPECT_NEAR(times[6], 1.0, 1e-9);
  for (std::size_t i = 1; i < times.size(); ++i) EXPECT_GT(times[i], times[i - 1]);
}

std::string start_error(const std::string& spec) {
  try {
    auto s = make_depth_source(spec);
    s->start();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "no error";
}

TEST(BagSource, ABrokenBagAMissingTopicAndAWrongEncodingNameTheFileTheTopicAndWhatItHolds) {
  const auto two = temp_bag("two.bag");
  {
    bag::Writer w(two.string());
    w.depth_mm("/a/depth", "/a/camera_info", kT0, 0, "a", cv::Mat1w(2, 2, std::uint16_t(1)),
               k_of(2, 2));
    w.depth_mm("/b/depth", "/b/camera_info", kT0, 0, "b", cv::Mat1w(2, 2, std::uint16_t(2)),
               k_of(2, 2));
    w.colour("/a/rgb", kT0, "a", cv::Mat3b(2, 2, cv::Vec3b(1, 2, 3)));
  }
  std::string e = start_error("bag:" + two.string());
  EXPECT_NE(e.find("2 depth image topics; choose one with topic=T"), std::string::npos) << e;
  EXPECT_NE(e.find("/a/depth (sensor_msgs/Image 16UC1, 1 messages)"), std::string::npos) << e;
  e = start_error("bag:" + two.string() + ",topic=/c/depth");
  EXPECT_NE(e.find(two.string() + " has no topic /c/depth; it holds"), std::string::npos) << e;
  e = start_error("bag:" + two.string() + ",topic=/a/rgb");
  EXPECT_NE(e.find("topic /a/rgb is sensor_msgs/Image bgr8, not a depth image"), std::string::npos)
      << e;
  e = start_error("bag:" + two.string() + ",topic=/a/depth,info=/nope");
  EXPECT_NE(e.find("no sensor_msgs/CameraInfo topic /nope"), std::string::npos) << e;
  // The sibling camera_info is the default: /b/depth takes /b/camera_info.
  auto b = make_depth_source("bag:" + two.string() + ",topic=/b/depth,fast");
  b->start();
  auto r = b->read(500ms);
  ASSERT_EQ(r.status, ReadStatus::Frame) << r.error;
  EXPECT_EQ(r.frame.image.depth_mm(0, 0), 2);

  const auto colour_only = temp_bag("colour.bag");
  {
    bag::Writer w(colour_only.string());
    w.colour("/rgb", kT0, "c", cv::Mat3b(2, 2, cv::Vec3b(1, 2, 3)));
  }
  e = start_error("bag:" + colour_only.string());
  EXPECT_NE(e.find("holds no depth image topic (sensor_msgs/Image 16UC1 or 32FC1); it holds /rgb "
                   "(sensor_msgs/Image bgr8, 1 messages)"),
            std::string::npos)
      << e;

  const auto no_info = temp_bag("noinfo.bag");
  {
    bag::Writer w(no_info.string());
    w.depth_mm("/d", "", kT0, 0, "c", cv::Mat1w(2, 2, std::uint16_t(1)), k_of(2, 2));
  }
  e = start_error("bag:" + no_info.string());
  EXPECT_NE(e.find("no intrinsics for /d: 0 sensor_msgs/CameraInfo topics"), std::string::npos)
      << e;

  const auto junk = temp_bag("junk.bag");
  std::ofstream(junk) << "#ROSBAG V2.0\nnot really a bag";
  e = start_error("bag:" + junk.string());
  EXPECT_NE(e.find("cannot read bag " + junk.string()), std::string::npos) << e;
  e = start_error("bag:" + temp_bag("absent.bag").string());
  EXPECT_NE(e.find("cannot read bag " + temp_bag("absent.bag").string()), std::string::npos) << e;

  EXPECT_THROW(make_depth_source("bag:x.bag,speed=2"), std::invalid_argument);
  EXPECT_THROW(make_depth_source("bag:x.bag,rate=0"), std::invalid_argument);
  EXPECT_THROW(make_depth_source("bag:x.bag,rate=2,fast"), std::invalid_argument);
  EXPECT_THROW(make_depth_source("bag:"), std::invalid_argument);
}

TEST(BagSource, ACameraInfoThatCannotProjectIsNamedBeforeTheFirstFrame) {
  const double nan = std::nan("");
  const double inf = std::numeric_limits<double>::infinity();
  struct Case {
    const char* name;
    bag::CameraIntrinsics k;
    const char* expect;
  };
  const std::vector<Case> cases = {
      {"zero_fx", {0.0, 571.1, 31.5, 25.5, 64, 48}, "fx (K[0]) = 0 is not a finite positive"},
      {"nan_fy", {570.3, nan, 31.5, 25.5, 64, 48}, "fy (K[4]) = nan is not a finite positive"},
      {"inf_cx", {570.3, 571.1, inf, 25.5, 64, 48}, "cx (K[2]) = inf is not a finite positive"},
      {"negative_cy", {570.3, 571.1, 31.5, -2.0, 64, 48}, "cy (K[5]) = -2 is not"},
  };
  for (const auto& c : cases) {
    EXPECT_NE(camera_info_error(c.k).find(c.expect), std::string::npos)
        << c.name << ": " << camera_info_error(c.k);
    const auto path = temp_bag(std::string(c.name) + ".bag");
    {
      bag::Writer w(path.string());
      w.depth_mm("/d/depth", "/d/camera_info", kT0, 0, "d", cv::Mat1w(48, 64, std::uint16_t(900)),
                 c.k);
    }
    const std::string e = start_error("bag:" + path.string());
    EXPECT_NE(e.find("CameraInfo topic /d/camera_info: " + std::string(c.expect).substr(0, 9)),
              std::string::npos)
        << c.name << ": " << e;
  }
  EXPECT_EQ(camera_info_error(k_of(64, 48)), "");
  EXPECT_NE(camera_info_error({570.3, 571.1, 31.5, 25.5, 0, 48}).find("not a positive image size"),
            std::string::npos);
}

TEST(BagSource, AColourTopicIsTheEyeViewOfBothEyes) {
  const auto path = temp_bag("rgb.bag");
  cv::Mat3b bgr(6, 8, cv::Vec3b(10, 20, 30));
  bgr(2, 3) = cv::Vec3b(200, 100, 50);
  {
    bag::Writer w(path.string());
    w.colour("/rgb", kT0, "c", bgr);
    w.depth_mm("/d", "/camera_info", kT0, 0, "c", cv::Mat1w(6, 8, std::uint16_t(900)), k_of(8, 6));
  }
  auto stereo = make_stereo_source("bag:" + path.string() + ",colour=/rgb,fast");
  stereo->start();
  auto r = stereo->read(500ms);
  ASSERT_EQ(r.status, ReadStatus::Frame) << r.error;
  EXPECT_EQ(cv::norm(r.frame.left_bgr, bgr, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(r.frame.right_bgr, bgr, cv::NORM_INF), 0.0);
  EXPECT_THROW(make_stereo_source("bag:" + path.string()), std::invalid_argument);
  auto wrong = make_stereo_source("bag:" + path.string() + ",colour=/nothing");
  EXPECT_THROW(wrong->start(), std::runtime_error);
}

}  // namespace
}  // namespace telex::remote
