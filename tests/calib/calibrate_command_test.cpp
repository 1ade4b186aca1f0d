// SPDX-License-Identifier: MIT
// `telex calibrate` as a process on rendered boards written to files: stereo then depth-eye into
// one rig file (the lab's order), against the renderer's known answers; and the error cases with
// their exit codes (2 for flags, 1 for a calibration that cannot be made).
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "calibrate_run.h"
#include "process.h"
#include "telex/calib/calibrate.h"
#include "telex/calib/render.h"
#include "telex/common/rig.h"
#include "test_support.h"

namespace telex::test {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;
using namespace telex::calib;

constexpr double kDeg = 180.0 / 3.14159265358979323846;

// Writes views as left_NN.png, right_NN.png, ir_NN.png, depth_NN.png.
void write_views(const fs::path& dir, const std::vector<RenderedView>& views) {
  fs::create_directories(dir);
  for (std::size_t i = 0; i < views.size(); ++i) {
    const std::string n = (i < 10 ? "0" : "") + std::to_string(i);
    ASSERT_TRUE(cv::imwrite((dir / ("left_" + n + ".png")).string(), views[i].left));
    ASSERT_TRUE(cv::imwrite((dir / ("right_" + n + ".png")).string(), views[i].right));
    ASSERT_TRUE(cv::imwrite((dir / ("ir_" + n + ".png")).string(), views[i].ir));
    ASSERT_TRUE(cv::imwrite((dir / ("depth_" + n + ".png")).string(), views[i].depth_mm));
  }
}

std::string glob(const fs::path& dir, const std::string& prefix) {
  return (dir / (prefix + "_*.png")).string();
}

double percent(double got, double want) { return 100.0 * (got - want) / want; }

TEST(CalibrateCommand, StereoThenDepthEyeOnRenderedBoards) {
  TELEX_REQUIRE_BINARIES("telex");
  const fs::path dir = scratch_dir("calibrate_rendered");
  const BoardSpec board = parse_board("9x6", 30.0);
  const RenderRig truth = example_render_rig();
  write_views(dir / "img", render_views(truth, board, 14, 5));
  // A 15th pair whose right image shows no board: named on stderr and skipped.
  const cv::Mat empty(480, 640, CV_8UC1, cv::Scalar(110));
  cv::imwrite((dir / "img" / "left_zz.png").string(),
              cv::imread((dir / "img" / "left_00.png").string(), cv::IMREAD_GRAYSCALE));
  cv::imwrite((dir / "img" / "right_zz.png").string(), empty);
  // The rig file exists with a key of its own, which the calibration must keep.
  const fs::path rig = dir / "rig.json";
  {
    std::ofstream f(rig);
    f << R"({"rig_version": 1, "operator": {"body": {"upper_arm_m": 0.31}}})"
      << "\n";
  }

  const CommandRun s = telex_calibrate(
      dir, "stereo",
      {"stereo", "--left", glob(dir / "img", "left"), "--right", glob(dir / "img", "right"),
       "--board", "9x6", "--square-mm", "30", "--out", rig.string(), "--json"});
  ASSERT_EQ(s.rc, 0) << s.err;
  EXPECT_NE(s.err.find("right_zz.png"), std::string::npos) << s.err;
  const auto j = nlohmann::json::parse(s.out);
  for (const char* key : {"rms_px", "baseline_m", "left", "right"})
    EXPECT_TRUE(j.contains(key)) << key;
  for (const char* eye : {"left", "right"})
    for (const char* key : {"fx_px", "fy_px", "cx_px", "cy_px"})
      EXPECT_TRUE(j[eye].contains(key)) << eye << "." << key;
  EXPECT_EQ(j["views"], 15);
  EXPECT_EQ(j["views_used"], 14);
  ASSERT_EQ(j["skipped"].size(), 1u);
  EXPECT_NE(j["skipped"][0].get<std::string>().find("right_zz.png"), std::string::npos);

  const double rms = j["rms_px"], baseline = j["baseline_m"];
  const double b_true = glm::length(truth.X_RightEyeLeftEye.translation_m);
  const double e_lfx = percent(j["left"]["fx_px"], truth.left.k.fx);
  const double e_lfy = percent(j["left"]["fy_px"], truth.left.k.fy);
  const double e_rfx = percent(j["right"]["fx_px"], truth.right.k.fx);
  const double e_rfy = percent(j["right"]["fy_px"], truth.right.k.fy);
  const double e_b = percent(baseline, b_true);
  std::printf(
      "[ measured ] telex calibrate stereo: RMS %.3f px; left fx %+.3f %% fy %+.3f %%; "
      "right fx %+.3f %% fy %+.3f %%; baseline %.2f mm (%+.3f %%)\n",
      rms, e_lfx, e_lfy, e_rfx, e_rfy, baseline * 1e3, e_b);
  EXPECT_LT(rms, 0.5);
  for (double e : {e_lfx, e_lfy, e_rfx, e_rfy, e_b}) EXPECT_LT(std::abs(e), 1.0);

  // The rig holds what the command printed, and kept the key it had.
  const Rig after = load_rig(rig);
  ASSERT_TRUE(after.eye[0] && after.eye[1] && after.X_RightEyeLeftEye);
  EXPECT_DOUBLE_EQ(after.eye[0]->k.fx, j["left"]["fx_px"].get<double>());
  EXPECT_DOUBLE_EQ(after.eye[1]->k.cy, j["right"]["cy_px"].get<double>());
  EXPECT_NEAR(*after.baseline_m(), baseline, 1e-12);
  EXPECT_LT(after.X_RightEyeLeftEye->translation_m.x, 0.0) << "p_right = R p_left + t";
  EXPECT_DOUBLE_EQ(after.body.upper_arm_m, 0.31);

  // depth-eye on the rig the stereo step wrote; the depth intrinsics from the flag.
  const Intrinsics& dk = truth.depth.k;
  const std::string intr = std::to_string(dk.fx) + "," + std::to_string(dk.fy) + "," +
                           std::to_string(dk.cx) + "," + std::to_string(dk.cy) + "," +
                           std::to_string(dk.width) + "," + std::to_string(dk.height);
  const CommandRun d =
      telex_calibrate(dir, "depth_eye",
                      {"depth-eye", "--ir", glob(dir / "img", "ir"), "--right",
                       (dir / "img" / "right_[0-9][0-9].png").string(), "--depth",
                       glob(dir / "img", "depth"), "--board", "9x6", "--square-mm", "30", "--rig",
                       rig.string(), "--depth-intrinsics", intr, "--json"});
  ASSERT_EQ(d.rc, 0) << d.err;
  const auto k = nlohmann::json::parse(d.out);
  ASSERT_EQ(k["translation_m"].size(), 3u);
  ASSERT_EQ(k["rotation_deg"].size(), 3u);
  const glm::dvec3 t(k["translation_m"][0], k["translation_m"][1], k["translation_m"][2]);
  const Rig final_rig = load_rig(rig);
  ASSERT_TRUE(final_rig.X_RightEyeDepth && final_rig.depth);
  EXPECT_EQ(*final_rig.depth, dk);
  EXPECT_LT(glm::length(final_rig.X_RightEyeDepth->translation_m - t), 1e-12);
  const double t_err_mm = glm::length(t - truth.X_RightEyeDepth.translation_m) * 1e3;
  const double r_err_deg = rotation_angle_between_rad(final_rig.X_RightEyeDepth->rotation,
                                                      truth.X_RightEyeDepth.rotation) *
                           kDeg;
  const double residual = k["residual_mm"];
  std::printf(
      "[ measured ] telex calibrate depth-eye: translation off %.3f mm, rotation off %.4f "
      "deg, residual %.3f mm, RMS %.3f px; depth planes: median offset %.3f mm, from "
      "planes alone %.3f mm / %.4f deg from the IR result\n",
      t_err_mm, r_err_deg, residual, k["rms_px"].get<double>(),
      k["depth_planes"]["offset_to_ir_plane_mm_median"].get<double>(),
      k["depth_planes"]["from_planes"]["differs_mm"].get<double>(),
      k["depth_planes"]["from_planes"]["differs_deg"].get<double>());
  EXPECT_LT(t_err_mm, 2.0);
  EXPECT_LT(r_err_deg, 0.2);
  EXPECT_LT(residual, 1.0);
  EXPECT_NEAR(k["rotation_angle_deg"].get<double>(),
              cv::norm(rotation_vector_rad(final_rig.X_RightEyeDepth->rotation)) * kDeg, 1e-9);
  EXPECT_LT(std::abs(k["depth_planes"]["offset_to_ir_plane_mm_median"].get<double>()), 1.0);
  EXPECT_LT(k["depth_planes"]["from_planes"]["differs_mm"].get<double>(), 3.0);
  // The other keys survived both updates.
  EXPECT_EQ(final_rig.eye[0]->k.fx, after.eye[0]->k.fx);
  EXPECT_DOUBLE_EQ(final_rig.body.upper_arm_m, 0.31);
}

TEST(CalibrateCommand, RenderWritesBoardsAndTheirTruth) {
  TELEX_REQUIRE_BINARIES("telex");
  const fs::path dir = scratch_dir("calibrate_render");
  const CommandRun r =
      telex_calibrate(dir, "render", {"render", "--out", (dir / "b").string(), "--views", "2"});
  ASSERT_EQ(r.rc, 0) << r.err;
  for (const char* f : {"left_00.png", "right_01.png", "ir_01.png", "depth_00.png", "truth.json"})
    EXPECT_TRUE(fs::exists(dir / "b" / f)) << f;
  EXPECT_EQ(cv::imread((dir / "b" / "depth_00.png").string(), cv::IMREAD_UNCHANGED).type(),
            CV_16UC1);
  std::ifstream f(dir / "b" / "truth.json");
  const auto j = nlohmann::json::parse(f);
  EXPECT_EQ(j["X_RightEyeBoard"].size(), 2u);
  // The truth is a valid rig: the answers the calibration should find.
  const Rig truth = parse_rig(j["truth"].dump(), "truth.json");
  ASSERT_TRUE(truth.eye[0]);
  EXPECT_DOUBLE_EQ(truth.eye[0]->k.fx, example_render_rig().left.k.fx);
}

// A few rendered pairs for the error cases (fewer than five: too few for a calibration).
class CalibrateErrors : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = scratch_dir(std::string("calibrate_errors_") +
                       ::testing::UnitTest::GetInstance()->current_test_info()->name());
    const BoardSpec board = parse_board("9x6", 30.0);
    write_views(dir_ / "img", render_views(example_render_rig(), board, 3, 9));
  }
  CommandRun stereo(const std::string& name, std::vector<std::string> extra) {
    std::vector<std::string> args{"stereo"};
    args.insert(args.end(), extra.begin(), extra.end());
    return telex_calibrate(dir_, name, args);
  }
  std::vector<std::string> good_flags() const {
    return {"--left",      glob(dir_ / "img", "left"),
            "--right",     glob(dir_ / "img", "right"),
            "--board",     "9x6",
            "--square-mm", "30",
            "--out",       (dir_ / "rig.json").string()};
  }
  fs::path dir_;
};

TEST_F(CalibrateErrors, FlagsExitTwoNamingTheFlag) {
  TELEX_REQUIRE_BINARIES("telex");
  struct Case {
    const char* name;
    std::vector<std::string> flags;
    const char* says;
  };
  const std::string left = glob(dir_ / "img", "left"), right = glob(dir_ / "img", "right");
  const std::string out = (dir_ / "rig.json").string();
  const std::vector<Case> cases{
      {"no_match",
       {"--left", (dir_ / "nothing_*.png").string(), "--right", right, "--board", "9x6",
        "--square-mm", "30", "--out", out},
       "matches no file"},
      {"counts",
       {"--left", left, "--right", (dir_ / "img" / "right_0[01].png").string(), "--board", "9x6",
        "--square-mm", "30", "--out", out},
       "matches 3 files but --right matches 2"},
      {"board_text",
       {"--left", left, "--right", right, "--board", "9by6", "--square-mm", "30", "--out", out},
       "is not CxR"},
      {"board_square",
       {"--left", left, "--right", right, "--board", "6x6", "--square-mm", "30", "--out", out},
       "square board"},
      {"square_mm",
       {"--left", left, "--right", right, "--board", "9x6", "--square-mm", "0", "--out", out},
       "--square-mm"},
      {"missing_out",
       {"--left", left, "--right", right, "--board", "9x6", "--square-mm", "30"},
       "--out"},
  };
  for (const Case& c : cases) {
    const CommandRun r = stereo(c.name, c.flags);
    EXPECT_EQ(r.rc, 2) << c.name << ": " << r.err;
    EXPECT_NE(r.err.find(c.says), std::string::npos) << c.name << ": " << r.err;
  }
  EXPECT_FALSE(fs::exists(dir_ / "rig.json")) << "nothing written on a flag error";

  // An --out that is not a rig is refused before any work, and left as it was.
  const fs::path other = dir_ / "other.json";
  std::ofstream(other) << R"({"not_a_rig_key": 1})"
                       << "\n";
  const CommandRun r = stereo("out_not_rig", {"--left", left, "--right", right, "--board", "9x6",
                                              "--square-mm", "30", "--out", other.string()});
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_NE(r.err.find("not_a_rig_key: unknown key"), std::string::npos) << r.err;
  EXPECT_EQ(read_text(other), "{\"not_a_rig_key\": 1}\n");
}

TEST_F(CalibrateErrors, TooFewFilesExitTwoBeforeDetectionAndMixedSizesExitOne) {
  TELEX_REQUIRE_BINARIES("telex");
  // Three files for five views is known before any image is read: a usage error at once.
  const CommandRun few = stereo("few", good_flags());
  EXPECT_EQ(few.rc, 2) << few.err;
  EXPECT_NE(few.err.find("--left matches 3 file(s) but at least 5 views are needed"),
            std::string::npos)
      << few.err;
  EXPECT_EQ(few.err.find("finding the board"), std::string::npos) << "no detection ran";
  // Five files, the board in three: found out by detection, exit 1 naming the views.
  const fs::path blanks = dir_ / "blank";
  fs::create_directories(blanks);
  const auto view = [](const std::string& eye, int v) {
    return eye + "_0" + std::to_string(v) + ".png";
  };
  for (const char* eye : {"left", "right"}) {
    for (int v = 0; v < 3; ++v) fs::copy_file(dir_ / "img" / view(eye, v), blanks / view(eye, v));
    const cv::Mat first = cv::imread((blanks / view(eye, 0)).string());
    for (int v = 3; v < 5; ++v)
      cv::imwrite((blanks / view(eye, v)).string(),
                  cv::Mat(first.size(), first.type(), cv::Scalar::all(128)));
  }
  const CommandRun unfound = stereo(
      "unfound", {"--left", glob(blanks, "left"), "--right", glob(blanks, "right"), "--board",
                  "9x6", "--square-mm", "30", "--out", (dir_ / "rig.json").string()});
  EXPECT_EQ(unfound.rc, 1) << unfound.err;
  EXPECT_NE(unfound.err.find("only 3 of 5 views; at least 5 are needed"), std::string::npos)
      << unfound.err;
  const CommandRun fewer = stereo("min_views", [&] {
    auto f = good_flags();
    f.insert(f.end(), {"--min-views", "3"});
    return f;
  }());
  // Three views may calibrate; what matters is that --min-views moved the bar.
  EXPECT_EQ(fewer.err.find("at least 5"), std::string::npos) << fewer.err;

  // One left image at another size.
  const fs::path one = dir_ / "img" / "left_01.png";
  cv::Mat small;
  cv::resize(cv::imread(one.string(), cv::IMREAD_GRAYSCALE), small, cv::Size(320, 240));
  cv::imwrite(one.string(), small);
  const CommandRun mixed = stereo("mixed", [&] {
    auto f = good_flags();
    f.insert(f.end(), {"--min-views", "3"});
    return f;
  }());
  EXPECT_EQ(mixed.rc, 1) << mixed.err;
  EXPECT_NE(mixed.err.find("mixed image sizes"), std::string::npos) << mixed.err;
  EXPECT_NE(mixed.err.find("left_01.png is 320x240"), std::string::npos) << mixed.err;
}

TEST_F(CalibrateErrors, DepthEyeNeedsTheRightEyeAndDepthIntrinsics) {
  TELEX_REQUIRE_BINARIES("telex");
  const std::vector<std::string> images{"depth-eye",
                                        "--ir",
                                        glob(dir_ / "img", "ir"),
                                        "--right",
                                        glob(dir_ / "img", "right"),
                                        "--board",
                                        "9x6",
                                        "--square-mm",
                                        "30"};
  auto with = [&](std::vector<std::string> more) {
    std::vector<std::string> a = images;
    a.insert(a.end(), more.begin(), more.end());
    return a;
  };
  const CommandRun missing =
      telex_calibrate(dir_, "missing_rig", with({"--rig", (dir_ / "absent.json").string()}));
  EXPECT_EQ(missing.rc, 2) << missing.err;
  EXPECT_NE(missing.err.find("absent.json"), std::string::npos) << missing.err;

  const fs::path rig = dir_ / "rig.json";
  update_rig_file(rig, nlohmann::json::object());
  const CommandRun no_eye = telex_calibrate(dir_, "no_eye", with({"--rig", rig.string()}));
  EXPECT_EQ(no_eye.rc, 2) << no_eye.err;
  EXPECT_NE(no_eye.err.find("has no eyes.right"), std::string::npos) << no_eye.err;

  update_rig_file(rig, {{"eyes", {{"right", camera_model_json(example_render_rig().right)}}}});
  const CommandRun no_depth = telex_calibrate(dir_, "no_depth", with({"--rig", rig.string()}));
  EXPECT_EQ(no_depth.rc, 2) << no_depth.err;
  EXPECT_NE(no_depth.err.find("--depth-intrinsics"), std::string::npos) << no_depth.err;

  const CommandRun bad_intr = telex_calibrate(
      dir_, "bad_intr", with({"--rig", rig.string(), "--depth-intrinsics", "570,570,320"}));
  EXPECT_EQ(bad_intr.rc, 2) << bad_intr.err;
  EXPECT_NE(bad_intr.err.find("FX,FY,CX,CY,W,H"), std::string::npos) << bad_intr.err;

  // IR images of another size than the depth intrinsics say: a data error.
  const CommandRun size =
      telex_calibrate(dir_, "ir_size",
                      with({"--rig", rig.string(), "--depth-intrinsics",
                            "570,570,319.5,239.5,320,240", "--min-views", "3"}));
  EXPECT_EQ(size.rc, 1) << size.err;
  EXPECT_NE(size.err.find("is 640x480 but --depth-intrinsics is 320x240"), std::string::npos)
      << size.err;

  const CommandRun few = telex_calibrate(
      dir_, "few",
      with({"--rig", rig.string(), "--depth-intrinsics", "570,570,319.5,239.5,640,480"}));
  EXPECT_EQ(few.rc, 2) << "three files for five views is known before detection: " << few.err;
  EXPECT_NE(few.err.find("--ir matches 3 file(s) but at least 5 views"), std::string::npos)
      << few.err;
  EXPECT_FALSE(load_rig(rig).X_RightEyeDepth) << "nothing written on failure";
}

}  // namespace
}  // namespace telex::test
