// SPDX-License-Identifier: MIT
// `telex capture` as a process: frames from each source kind written as the source delivered them
// (bit-exact against the files and the bag they came from), eye images when the run has an eye
// view, and clear errors for a bad spec, a source that ends early and an unwritable directory.
#include <gtest/gtest.h>

#include <chrono>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "daemons.h"
#include "driver_child.h"
#include "process.h"
#include "telex/bag/bag.h"
#include "telex/remote/openni_record.h"
#include "telex/remote/sources.h"
#include "test_support.h"

namespace telex::test {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;

struct CaptureRun {
  int rc = -1;
  std::string out, err;
};

CaptureRun capture(const fs::path& dir, std::vector<std::string> args, const std::string& name) {
  std::vector<std::string> argv{built_binary("telex").string(), "capture"};
  argv.insert(argv.end(), args.begin(), args.end());
  Process p(argv, dir / (name + ".out"), dir / (name + ".err"));
  const auto rc = p.wait(60s);
  EXPECT_TRUE(rc.has_value()) << "telex capture did not finish";
  return {rc.value_or(-1), p.stdout_text(), p.stderr_text()};
}

nlohmann::json capture_json(const fs::path& out) {
  std::ifstream is(out / "capture.json");
  return nlohmann::json::parse(is);
}

cv::Mat read_png(const fs::path& p) { return cv::imread(p.string(), cv::IMREAD_UNCHANGED); }

bool same(const cv::Mat& a, const cv::Mat& b) {
  return a.size() == b.size() && a.type() == b.type() && cv::norm(a, b, cv::NORM_INF) == 0;
}

TEST(Capture, SyntheticFramesAndEyesEveryKthFrame) {
  TELEX_REQUIRE_BINARIES("telex");
  const auto dir = scratch_dir("capture_synthetic");
  const auto out = dir / "out";
  const CaptureRun r = capture(dir,
                               {"--source", "synthetic:sphere", "--stereo", "synthetic:sphere",
                                "--frames", "3", "--every", "2", "--out", out.string(), "--json"},
                               "run");
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto j = capture_json(out);
  EXPECT_EQ(j["frames"], 3);
  EXPECT_EQ(j["frames_read"], 5);  // frames 0, 2 and 4 of those read
  EXPECT_EQ(j["eye_frames"], 3);
  EXPECT_EQ(j["intrinsics"]["width"], 640);
  ASSERT_EQ(j["files"].size(), 3u);
  std::uint64_t last_id = 0;
  for (std::size_t i = 0; i < 3; ++i) {
    const auto& f = j["files"][i];
    const cv::Mat depth = read_png(out / f["file"].get<std::string>());
    ASSERT_EQ(depth.type(), CV_16UC1) << f["file"];
    EXPECT_EQ(depth.cols, 640);
    EXPECT_GT(cv::countNonZero(depth), 640 * 480 / 2) << "a sphere scene is mostly surface";
    const cv::Mat left = read_png(out / f["left"].get<std::string>());
    EXPECT_EQ(left.type(), CV_8UC3);
    EXPECT_FALSE(read_png(out / f["right"].get<std::string>()).empty());
    if (i > 0) {
      EXPECT_EQ(f["frame_id"].get<std::uint64_t>(), last_id + 2) << "every second frame";
    }
    last_id = f["frame_id"];
  }
  EXPECT_FALSE(fs::exists(out / "depth_000003_mm.png"));
}

TEST(Capture, FilesComeBackBitExact) {
  TELEX_REQUIRE_BINARIES("telex");
  TELEX_REQUIRE_REAL_DATA();
  const auto desk = real_data_dir() / "desk";
  const auto dir = scratch_dir("capture_files");
  const auto out = dir / "out";
  const CaptureRun r = capture(dir,
                               {"--source", "files:" + (desk / "desk_*_depth_mm.png").string(),
                                "--frames", "3", "--out", out.string()},
                               "run");
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_NE(r.out.find("3 depth frames (0 with eye images)"), std::string::npos) << r.out;
  for (int i = 0; i < 3; ++i) {
    const auto want = read_png(desk / ("desk_" + std::to_string(i) + "_depth_mm.png"));
    char name[32];
    std::snprintf(name, sizeof name, "depth_%06d_mm.png", i);
    EXPECT_TRUE(same(read_png(out / name), want)) << name;
  }
}

TEST(Capture, ABagsDepthAndColourComeBackAsRecorded) {
  TELEX_REQUIRE_BINARIES("telex");
  const auto dir = scratch_dir("capture_bag");
  const auto bag_path = dir / "in.bag";
  std::vector<cv::Mat1w> depth;
  std::vector<cv::Mat3b> colour;
  {
    bag::Writer w(bag_path.string());
    cv::RNG rng(7);
    for (int i = 0; i < 4; ++i) {
      cv::Mat1w d(48, 64);
      rng.fill(d, cv::RNG::UNIFORM, 0, 65536);
      cv::Mat3b c(48, 64);
      rng.fill(c, cv::RNG::UNIFORM, 0, 256);
      const std::int64_t t = 1'700'000'000'000'000'000 + i * 33'333'333;
      w.depth_mm("/cam/depth", "/cam/camera_info", t, static_cast<std::uint32_t>(i), "cam", d,
                 {60, 60, 31.5, 23.5, 64, 48});
      w.colour("/cam/rgb", t, "cam", c);
      depth.push_back(d);
      colour.push_back(c);
    }
  }
  const auto out = dir / "out";
  const CaptureRun r = capture(dir,
                               {"--source", "bag:" + bag_path.string() + ",colour=/cam/rgb,fast",
                                "--frames", "4", "--out", out.string(), "--json"},
                               "run");
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto j = capture_json(out);
  EXPECT_EQ(j["intrinsics"]["fx"], 60.0);
  EXPECT_EQ(j["eye_frames"], 4);
  for (int i = 0; i < 4; ++i) {
    const auto& f = j["files"][i];
    EXPECT_TRUE(same(read_png(out / f["file"].get<std::string>()), depth[i])) << i;
    EXPECT_TRUE(same(read_png(out / f["left"].get<std::string>()), colour[i])) << i;
    EXPECT_TRUE(same(read_png(out / f["right"].get<std::string>()), colour[i])) << i;
  }
}

// An .oni recorded here from OpenNI2's Dummy device: the capture holds the file's frames in order,
// pixel for pixel, as this process's own oni source plays them. OpenNI2 runs in a forked child
// (run_driver_test, as the sources tests do): its Dummy and OniFile drivers have teardown races.
void oni_recording_comes_back_frame_for_frame() {
  const auto dir = scratch_dir("capture_oni");
  const auto oni = dir / "dummy.oni";
  ASSERT_EQ(remote::record_oni_frames("Dummy", oni, 8).frames(), 8);
  std::vector<cv::Mat1w> played;
  {
    auto source = remote::make_depth_source("oni:" + oni.string() + ",fast");
    source->start();
    for (int i = 0; i < 100; ++i) {
      auto f = source->read(std::chrono::milliseconds(200));
      if (f.status == remote::ReadStatus::EndOfStream) break;
      if (f.status == remote::ReadStatus::Frame) played.push_back(f.frame.image.depth_mm.clone());
    }
    source->stop();
  }
  ASSERT_GE(played.size(), 5u);
  const auto out = dir / "out";
  const CaptureRun r = capture(dir,
                               {"--source", "oni:" + oni.string() + ",fast", "--frames", "5",
                                "--out", out.string(), "--json"},
                               "run");
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto j = capture_json(out);
  EXPECT_EQ(j["intrinsics"]["width"], 320);
  for (int i = 0; i < 5; ++i)
    EXPECT_TRUE(same(read_png(out / j["files"][i]["file"].get<std::string>()), played[i])) << i;
}

TEST(Capture, AnOniRecordingComesBackFrameForFrame) {
  TELEX_REQUIRE_BINARIES("telex");
  run_driver_test(oni_recording_comes_back_frame_for_frame);
}

// OpenNI2's own test device, live: 320x240 frames whose top row is the Dummy's 2 m.
TEST(Capture, TheOpenNiDummyDeviceLive) {
  TELEX_REQUIRE_BINARIES("telex");
  const auto dir = scratch_dir("capture_dummy");
  const auto out = dir / "out";
  const CaptureRun r = capture(
      dir, {"--source", "openni:Dummy", "--frames", "3", "--out", out.string(), "--json"}, "run");
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto j = capture_json(out);
  ASSERT_EQ(j["files"].size(), 3u);
  for (int i = 0; i < 3; ++i) {
    const cv::Mat d = read_png(out / j["files"][i]["file"].get<std::string>());
    ASSERT_EQ(d.type(), CV_16UC1);
    EXPECT_EQ(d.cols, 320);
    EXPECT_EQ(d.rows, 240);
    EXPECT_EQ(cv::countNonZero(d.row(0) == 2000), 320) << "the Dummy's top row is 2 m";
  }
}

// --ir on OpenNI2's Dummy device: its driver offers depth and colour streams only, so the capture
// stops at start with the device and the missing stream named (exit 1), writing no frame.
TEST(Capture, IrOnTheOpenNiDummyDeviceNamesTheMissingIrStream) {
  TELEX_REQUIRE_BINARIES("telex");
  const auto dir = scratch_dir("capture_dummy_ir");
  const auto out = dir / "out";
  const CaptureRun r = capture(
      dir, {"--source", "openni:Dummy", "--ir", "--frames", "2", "--out", out.string()}, "run");
  EXPECT_EQ(r.rc, 1) << r.err;
  EXPECT_NE(r.err.find("--ir: OpenNI2 device 'Dummy' has no IR stream (SENSOR_IR)"),
            std::string::npos)
      << r.err;
  EXPECT_FALSE(fs::exists(out / "ir_000000.png"));
}

TEST(Capture, BadSpecEarlyEndAndUnwritableDirectoryAreNamed) {
  TELEX_REQUIRE_BINARIES("telex");
  const auto dir = scratch_dir("capture_errors");
  CaptureRun r = capture(dir, {"--source", "kinect:0", "--out", (dir / "a").string()}, "spec");
  EXPECT_EQ(r.rc, 2);
  EXPECT_NE(r.err.find("unknown depth source 'kinect'"), std::string::npos) << r.err;

  r = capture(dir, {"--source", "synthetic:plane", "--frames", "0", "--out", (dir / "b").string()},
              "frames");
  EXPECT_EQ(r.rc, 2) << "a flag out of range is a usage error";

  const auto bag_path = dir / "two.bag";
  {
    bag::Writer w(bag_path.string());
    for (int i = 0; i < 2; ++i)
      w.depth_mm("/d", "/camera_info", 1'700'000'000'000'000'000 + i * 1000,
                 static_cast<std::uint32_t>(i), "c", cv::Mat1w(4, 4, std::uint16_t(800)),
                 {5, 5, 1.5, 1.5, 4, 4});
  }
  r = capture(dir,
              {"--source", "bag:" + bag_path.string() + ",fast", "--frames", "5", "--out",
               (dir / "c").string()},
              "short");
  EXPECT_EQ(r.rc, 1);
  EXPECT_NE(r.err.find("ended after 2 frames (2 kept of 5 asked)"), std::string::npos) << r.err;
  EXPECT_TRUE(fs::exists(dir / "c" / "depth_000001_mm.png")) << "what was read is kept";
  EXPECT_EQ(capture_json(dir / "c")["frames"], 2) << "and listed in capture.json";

  std::ofstream(dir / "file") << "x";
  r = capture(dir, {"--source", "synthetic:plane", "--out", (dir / "file" / "sub").string()},
              "unwritable");
  EXPECT_EQ(r.rc, 1);
  EXPECT_NE(r.err.find("cannot create " + (dir / "file" / "sub").string()), std::string::npos)
      << r.err;

  r = capture(dir,
              {"--source", "bag:" + (dir / "none.bag").string(), "--out", (dir / "d").string()},
              "missing");
  EXPECT_EQ(r.rc, 1);
  EXPECT_NE(r.err.find((dir / "none.bag").string()), std::string::npos) << r.err;
}

TEST(Capture, CtrlCKeepsACompleteCaptureJsonOfWhatWasWritten) {
  TELEX_REQUIRE_BINARIES("telex");
  const auto dir = scratch_dir("capture_interrupted");
  const auto out = dir / "out";
  Process p({built_binary("telex").string(), "capture", "--source", "synthetic:plane", "--frames",
             "1000000", "--out", out.string()},
            dir / "run.out", dir / "run.err");
  ASSERT_TRUE(eventually(30s, [&] { return fs::exists(out / "depth_000002_mm.png"); }))
      << "no frames written";
  p.signal(SIGINT);
  const auto rc = p.wait(30s);
  ASSERT_TRUE(rc.has_value()) << "telex capture did not stop on SIGINT";
  EXPECT_EQ(*rc, 130) << p.stderr_text();
  const auto j = capture_json(out);
  EXPECT_FALSE(j["complete"].get<bool>());
  EXPECT_EQ(j["ended_by"], "signal");
  int pngs = 0;
  for (const auto& e : fs::directory_iterator(out))
    if (e.path().filename().string().starts_with("depth_")) ++pngs;
  EXPECT_GE(j["frames"].get<int>(), 3);
  EXPECT_EQ(j["frames"].get<int>(), pngs) << "every frame written is listed, and only those";
  ASSERT_EQ(j["files"].size(), static_cast<std::size_t>(pngs));
  for (const auto& row : j["files"]) EXPECT_TRUE(fs::exists(out / row["file"].get<std::string>()));
  EXPECT_NE(p.stdout_text().find("interrupted"), std::string::npos) << p.stdout_text();
}

}  // namespace
}  // namespace telex::test
