// SPDX-License-Identifier: MIT
// `telex process` end to end: files written, JSON fields, same result as the library, exit codes.
#include "process.h"

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>

#include "telex/common/depth_io.h"
#include "telex/common/hole_fill.h"
#include "telex/common/registration.h"
#include "telex/common/synthetic.h"
#include "test_support.h"

namespace telex {
namespace {

struct ToolRun {
  int exit_code = -1;
  std::string out;  // stdout
  std::string err;  // stderr
};

ToolRun run_telex(const std::string& args, const std::filesystem::path& err_file) {
  const auto bin = telex::test::built_binary("telex");
  EXPECT_TRUE(std::filesystem::exists(bin)) << bin << " not built";
  const std::string cmd = "'" + bin.string() + "' " + args + " 2>'" + err_file.string() + "'";
  ToolRun r;
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return r;
  std::array<char, 4096> buf;
  std::size_t n;
  while ((n = fread(buf.data(), 1, buf.size(), p)) > 0) r.out.append(buf.data(), n);
  const int status = pclose(p);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  if (FILE* e = fopen(err_file.c_str(), "r")) {
    while ((n = fread(buf.data(), 1, buf.size(), e)) > 0) r.err.append(buf.data(), n);
    fclose(e);
  }
  return r;
}

class ProcessCommand : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = ::telex::test::scratch_dir("process");
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::filesystem::path dir_;
};

TEST_F(ProcessCommand, RealFrameWritesFilesAndJson) {
  TELEX_REQUIRE_REAL_DATA();
  const auto in = telex::test::real_data_dir() / "desk" / "desk_1_depth_mm.png";
  const auto out = dir_ / "out";
  const ToolRun r = run_telex(
      "process --in '" + in.string() + "' --cx 320 --cy 240 --out '" + out.string() + "' --json",
      dir_ / "stderr.txt");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j.at("width").get<int>(), 640);
  EXPECT_EQ(j.at("height").get<int>(), 480);
  const cv::Mat1w d = cv::imread(in.string(), cv::IMREAD_ANYDEPTH);
  EXPECT_EQ(j.at("holes_in").get<std::size_t>(), count_holes(d));
  EXPECT_LE(j.at("holes_out").get<std::size_t>(), j.at("holes_in").get<std::size_t>() / 20);
  for (const char* key : {"load_ms", "fill_ms", "bilateral_ms", "normals_ms"})
    EXPECT_GE(j.at(key).get<double>(), 0.0) << key;
  EXPECT_GT(j.at("valid_normals").get<std::size_t>(), 250000u);

  const cv::Mat filled =
      cv::imread(j.at("outputs").at("filled_depth_mm").get<std::string>(), cv::IMREAD_ANYDEPTH);
  ASSERT_EQ(filled.type(), CV_16UC1);
  // The tool's filled depth is exactly the library's with default options.
  EXPECT_EQ(cv::norm(filled, fill_holes_mode(d).depth_mm, cv::NORM_INF), 0.0);
  for (const char* key : {"normals_rgb", "depth_colour"}) {
    const cv::Mat img =
        cv::imread(j.at("outputs").at(key).get<std::string>(), cv::IMREAD_UNCHANGED);
    ASSERT_FALSE(img.empty()) << key;
    EXPECT_EQ(img.type(), CV_8UC3) << key;
    EXPECT_EQ(img.size(), cv::Size(640, 480)) << key;
  }
}

TEST_F(ProcessCommand, TumUnitsSyntheticFrame) {
  const auto r =
      synth::render(synth::Scene::named("desk"), kinect_v1_intrinsics(), synth::SensorModel{}, 2);
  cv::Mat1w tum;
  r.depth.depth_mm.convertTo(tum, CV_16U, 5.0);  // 1/5000 m units
  const auto in = dir_ / "synthetic_tum.png";
  ASSERT_TRUE(cv::imwrite(in.string(), tum));
  const ToolRun run =
      run_telex("process --in '" + in.string() + "' --units tum --json", dir_ / "e.txt");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const auto j = nlohmann::json::parse(run.out);
  EXPECT_EQ(j.at("holes_in").get<std::size_t>(), count_holes(r.depth.depth_mm));
  EXPECT_FALSE(j.contains("outputs"));  // no --out: nothing written
}

TEST_F(ProcessCommand, RegistersBeforeFilling) {
  const auto r =
      synth::render(synth::Scene::named("box"), kinect_v1_intrinsics(), synth::SensorModel{}, 3);
  const auto in = dir_ / "box.png";
  save_depth_png(in, r.depth.depth_mm);
  const auto out = dir_ / "out";
  const ToolRun run = run_telex("process --in '" + in.string() + "' --register-shift 12.5 " +
                                    "--register-scale 1.05 --out '" + out.string() + "' --json",
                                dir_ / "e.txt");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const auto j = nlohmann::json::parse(run.out);
  EXPECT_GE(j.at("register_ms").get<double>(), 0.0);
  ShiftScale params;
  params.shift_x_px = 12.5;
  params.scale_x = params.scale_y = 1.05;
  const DepthImage registered = register_shift_scale(r.depth, params, r.depth.intrinsics);
  EXPECT_EQ(j.at("holes_in").get<std::size_t>(), count_holes(registered.depth_mm));
  const cv::Mat filled =
      cv::imread(j.at("outputs").at("filled_depth_mm").get<std::string>(), cv::IMREAD_ANYDEPTH);
  EXPECT_EQ(cv::norm(filled, fill_holes_mode(registered.depth_mm).depth_mm, cv::NORM_INF), 0.0);
  // Without the flags nothing is registered.
  const ToolRun plain = run_telex("process --in '" + in.string() + "' --json", dir_ / "e.txt");
  ASSERT_EQ(plain.exit_code, 0) << plain.err;
  EXPECT_FALSE(nlohmann::json::parse(plain.out).contains("register_ms"));
  EXPECT_EQ(
      run_telex("process --in '" + in.string() + "' --register-scale 0", dir_ / "e.txt").exit_code,
      1);
}

TEST_F(ProcessCommand, BadInputExitsOneNamingTheFile) {
  const ToolRun missing =
      run_telex("process --in '" + (dir_ / "nope.png").string() + "'", dir_ / "e.txt");
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_NE(missing.err.find("nope.png"), std::string::npos) << missing.err;
  const auto eight_bit = dir_ / "rgb.png";
  ASSERT_TRUE(cv::imwrite(eight_bit.string(), cv::Mat3b(4, 4, cv::Vec3b(1, 2, 3))));
  const ToolRun wrong = run_telex("process --in '" + eight_bit.string() + "'", dir_ / "e.txt");
  EXPECT_EQ(wrong.exit_code, 1);
  EXPECT_NE(wrong.err.find("rgb.png"), std::string::npos) << wrong.err;
}

TEST_F(ProcessCommand, RunsReportsWarmMediansAndTheFirstRunApart) {
  const auto r =
      synth::render(synth::Scene::named("desk"), kinect_v1_intrinsics(), synth::SensorModel{}, 2);
  const auto in = dir_ / "desk.png";
  ASSERT_TRUE(cv::imwrite(in.string(), r.depth.depth_mm));
  const ToolRun one = run_telex("process --in '" + in.string() + "' --runs 1 --json", dir_ / "e1");
  const ToolRun four = run_telex("process --in '" + in.string() + "' --runs 4 --json", dir_ / "e4");
  ASSERT_EQ(one.exit_code, 0) << one.err;
  ASSERT_EQ(four.exit_code, 0) << four.err;
  const auto j1 = nlohmann::json::parse(one.out);
  const auto j4 = nlohmann::json::parse(four.out);
  EXPECT_EQ(j1.at("runs").get<int>(), 1);
  EXPECT_EQ(j4.at("runs").get<int>(), 4);
  for (const char* key : {"fill_ms", "bilateral_ms", "normals_ms"}) {
    // One run: nothing warm to report, so the figure is that run's.
    EXPECT_EQ(j1.at(key).get<double>(), j1.at("first_run").at(key).get<double>()) << key;
    EXPECT_GE(j4.at("first_run").at(key).get<double>(), 0.0) << key;
  }
  // Repeating the stages changes the timing, never the result.
  for (const char* key : {"holes_in", "holes_out", "fill_passes", "valid_normals"})
    EXPECT_EQ(j1.at(key), j4.at(key)) << key;
  EXPECT_EQ(run_telex("process --in '" + in.string() + "' --runs 0", dir_ / "e0").exit_code, 2);
}

TEST_F(ProcessCommand, BadFlagsExitTwo) {
  const auto in = dir_ / "d.png";
  ASSERT_TRUE(cv::imwrite(in.string(), cv::Mat1w(8, 8, std::uint16_t{900})));
  EXPECT_EQ(
      run_telex("process --in '" + in.string() + "' --units furlongs", dir_ / "e.txt").exit_code,
      2);
  EXPECT_EQ(run_telex("process", dir_ / "e.txt").exit_code, 2);
  EXPECT_EQ(
      run_telex("process --in '" + in.string() + "' --fill-passes x", dir_ / "e.txt").exit_code, 2);
}

}  // namespace
}  // namespace telex
