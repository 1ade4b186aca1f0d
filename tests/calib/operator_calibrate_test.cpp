// SPDX-License-Identifier: MIT
// `telex calibrate body|glove` on generated captures with known answers: T-poses with and without
// elbow markers under 2 mm marker noise, bent and moving arms, flat-hand and fist glove reports
// and a dead sensor; the library directly and the command as a process writing a rig file.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "calibrate_run.h"
#include "process.h"
#include "telex/calib/operator.h"
#include "telex/common/rig.h"
#include "test_support.h"

namespace telex::test {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;
using namespace telex::calib;

constexpr double kPi = 3.14159265358979323846;

// The rig's default body ids: right hand 2, right shoulder 3; these add the left side and elbows.
constexpr int kRightShoulder = 3, kRightWrist = 2, kRightElbow = 6;
constexpr int kLeftShoulder = 4, kLeftWrist = 5, kLeftElbow = 7;

struct TPose {
  double upper_arm_m = 0.30, forearm_m = 0.30 * 0.146 / 0.186;
  bool elbows = false;
  bool left = true;
  double elbow_bend_rad = 0.0;   // held bent: the forearm turned forward (-z) by this
  double elbow_swing_rad = 0.0;  // bending and straightening during the capture, peak
  double noise_m = 0.002;        // per axis, per marker
  int frames = 360;              // 3 s at 120 Hz
  std::uint32_t seed = 13;
};

// Rows of the station's --log-tracking CSV: the operator in a T-pose facing -z (Motive: y up),
// swaying a few millimetres, every marker with Gaussian noise.
std::string tpose_csv(const TPose& t) {
  std::mt19937 rng(t.seed);
  std::normal_distribution<double> noise(0.0, t.noise_m);
  std::string csv = "time_s,body_id,x_m,y_m,z_m,qx,qy,qz,qw,valid\n";
  auto row = [&](double time_s, int id, glm::dvec3 p) {
    p += glm::dvec3{noise(rng), noise(rng), noise(rng)};
    char buf[160];
    std::snprintf(buf, sizeof buf, "%.6f,%d,%.6f,%.6f,%.6f,0,0,0,1,1\n", time_s, id, p.x, p.y, p.z);
    csv += buf;
  };
  for (int i = 0; i < t.frames; ++i) {
    const double time_s = i / 120.0;
    const glm::dvec3 sway{0.004 * std::sin(time_s * 2.0), 0.0, 0.003 * std::cos(time_s * 1.3)};
    const double bend =
        t.elbow_bend_rad + t.elbow_swing_rad * 0.5 * (1.0 - std::cos(2.0 * kPi * time_s / 3.0));
    for (int side : {+1, -1}) {
      if (side < 0 && !t.left) continue;
      const glm::dvec3 shoulder = glm::dvec3{0.18 * side, 1.45, 0.0} + sway;
      const glm::dvec3 elbow = shoulder + glm::dvec3{t.upper_arm_m * side, 0.0, 0.0};
      const glm::dvec3 wrist =
          elbow + t.forearm_m * glm::dvec3{std::cos(bend) * side, 0.0, -std::sin(bend)};
      row(time_s, side > 0 ? kRightShoulder : kLeftShoulder, shoulder);
      row(time_s, side > 0 ? kRightWrist : kLeftWrist, wrist);
      if (t.elbows) row(time_s, side > 0 ? kRightElbow : kLeftElbow, elbow);
    }
  }
  return csv;
}

fs::path write(const fs::path& path, const std::string& text) {
  std::ofstream f(path);
  f << text;
  return path;
}

std::vector<TrackingFrame> frames_of(const fs::path& dir, const std::string& name, const TPose& t) {
  return load_tracking_csv(write(dir / (name + ".csv"), tpose_csv(t)));
}

ArmBodies right_arm(bool elbows, bool both) {
  return {kRightShoulder, kRightWrist, elbows ? kRightElbow : -1, both ? kLeftShoulder : -1};
}

TEST(OperatorCalibration, ElbowMarkersGiveEachSegment) {
  const fs::path dir = scratch_dir("calibrate_body_lib");
  TPose t;
  t.upper_arm_m = 0.33;  // not the ratio: the markers measure each segment
  t.forearm_m = 0.25;
  t.elbows = true;
  const ArmCalibration a =
      calibrate_arm(frames_of(dir, "elbows", t), right_arm(true, true), "right");
  std::printf("[ measured ] elbow markers: upper arm %+.2f mm, forearm %+.2f mm, spread %.2f mm\n",
              (a.upper_arm_m - t.upper_arm_m) * 1e3, (a.forearm_m - t.forearm_m) * 1e3,
              a.spread_m * 1e3);
  EXPECT_TRUE(a.from_elbow);
  EXPECT_EQ(a.samples, 360);
  EXPECT_NEAR(a.upper_arm_m, 0.33, 0.005);
  EXPECT_NEAR(a.forearm_m, 0.25, 0.005);
  EXPECT_NEAR(a.reach_m, 0.58, 0.005);
}

TEST(OperatorCalibration, WithoutElbowsTheRatioSplitsTheReach) {
  const fs::path dir = scratch_dir("calibrate_body_lib");
  TPose t;  // segments in Drillis & Contini's ratio
  const ArmCalibration a =
      calibrate_arm(frames_of(dir, "ratio", t), right_arm(false, false), "right");
  std::printf("[ measured ] ratio: upper arm %+.2f mm, forearm %+.2f mm, spread %.2f mm\n",
              (a.upper_arm_m - t.upper_arm_m) * 1e3, (a.forearm_m - t.forearm_m) * 1e3,
              a.spread_m * 1e3);
  EXPECT_FALSE(a.from_elbow);
  EXPECT_NEAR(a.upper_arm_m, t.upper_arm_m, 0.005);
  EXPECT_NEAR(a.forearm_m, t.forearm_m, 0.005);
  EXPECT_LT(a.spread_m, 0.01);
}

TEST(OperatorCalibration, BentArmsAreRejectedNamingTheSide) {
  const fs::path dir = scratch_dir("calibrate_body_lib");
  TPose bent;
  bent.elbows = true;
  bent.elbow_bend_rad = 40.0 * kPi / 180.0;
  const auto f1 = frames_of(dir, "bent_elbows", bent);
  try {
    calibrate_arm(f1, right_arm(true, false), "right");
    ADD_FAILURE() << "a 40 deg elbow was accepted";
  } catch (const CalibrationError& e) {
    EXPECT_NE(std::string(e.what()).find("right arm: the elbow is bent"), std::string::npos)
        << e.what();
  }
  // No elbow markers: the wrist leaves the shoulder line.
  bent.elbows = false;
  const auto f2 = frames_of(dir, "bent", bent);
  try {
    calibrate_arm(f2, {kLeftShoulder, kLeftWrist, -1, kRightShoulder}, "left");
    ADD_FAILURE() << "a 40 deg elbow was accepted without elbow markers";
  } catch (const CalibrationError& e) {
    EXPECT_NE(std::string(e.what()).find("left arm: the wrist is"), std::string::npos) << e.what();
  }
  // Bending during the capture: the reach spreads.
  TPose moving;
  moving.left = false;
  moving.elbow_swing_rad = 30.0 * kPi / 180.0;
  try {
    calibrate_arm(frames_of(dir, "moving", moving), right_arm(false, false), "right");
    ADD_FAILURE() << "an arm bending during the capture was accepted";
  } catch (const CalibrationError& e) {
    EXPECT_NE(std::string(e.what()).find("right arm: the shoulder-to-wrist distance spreads"),
              std::string::npos)
        << e.what();
  }
  // A straight arm passes the same checks (the rejections are not from the noise).
  EXPECT_NO_THROW(
      calibrate_arm(frames_of(dir, "straight", TPose{}), right_arm(false, true), "right"));
}

TEST(OperatorCalibration, TooFewValidSamplesAreRejected) {
  const fs::path dir = scratch_dir("calibrate_body_lib");
  TPose t;
  t.frames = 20;
  try {
    calibrate_arm(frames_of(dir, "short", t), right_arm(false, false), "right");
    ADD_FAILURE() << "20 frames were accepted";
  } catch (const CalibrationError& e) {
    EXPECT_NE(std::string(e.what()).find("right arm: only 20 of 20 frames"), std::string::npos)
        << e.what();
  }
}

// ---- glove
// ---------------------------------------------------------------------------------------

struct GloveTruth {
  std::vector<double> flat, fist;
};

GloveTruth glove_truth(int n) {
  GloveTruth g;
  for (int i = 0; i < n; ++i) {
    const bool used = glove_sensor_used(n, i);
    g.flat.push_back(0.08 + 0.01 * i);
    g.fist.push_back(used ? 0.55 + 0.015 * i : 0.08 + 0.01 * i + 0.01);  // abduction barely moves
  }
  return g;
}

std::string glove_csv(const std::vector<double>& level, std::uint32_t seed, int dead = -1) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.004);
  std::string csv = "time_s";
  for (std::size_t i = 0; i < level.size(); ++i) csv += ",s" + std::to_string(i);
  csv += "\n";
  for (int r = 0; r < 300; ++r) {
    csv += std::to_string(r / 100.0);
    for (std::size_t i = 0; i < level.size(); ++i) {
      const double v = static_cast<int>(i) == dead ? 0.0 : level[i] + noise(rng);
      char buf[32];
      std::snprintf(buf, sizeof buf, ",%.5f", v);
      csv += buf;
    }
    csv += "\n";
  }
  return csv;
}

TEST(OperatorCalibration, GloveRangeFromFlatAndFist) {
  const fs::path dir = scratch_dir("calibrate_glove_lib");
  for (int n : {5, 14}) {
    const GloveTruth g = glove_truth(n);
    const GloveCapture flat =
        load_glove_csv(write(dir / ("flat" + std::to_string(n) + ".csv"), glove_csv(g.flat, 1)));
    const GloveCapture fist =
        load_glove_csv(write(dir / ("fist" + std::to_string(n) + ".csv"), glove_csv(g.fist, 2)));
    ASSERT_EQ(flat.sensor_count, n);
    const GloveCalibResult r = calibrate_glove(flat, fist);
    ASSERT_EQ(r.range.min.size(), static_cast<std::size_t>(n));
    for (int i = 0; i < n; ++i) {
      if (!glove_sensor_used(n, i)) {
        EXPECT_EQ(r.range.min[i], 0.0) << i;
        EXPECT_EQ(r.range.max[i], 1.0) << i;
        continue;
      }
      // The 5th / 95th percentile sits 1.645 noise sigmas (6.6e-3) inside the phase's spread.
      EXPECT_NEAR(r.range.min[i], g.flat[i], 0.01) << glove_sensor_name(n, i);
      EXPECT_NEAR(r.range.max[i], g.fist[i], 0.01) << glove_sensor_name(n, i);
    }
    EXPECT_EQ(r.full_range_sensors, (n == 14 ? std::vector<int>{2, 5, 8, 11} : std::vector<int>{}));
  }
}

TEST(OperatorCalibration, DeadGloveSensorIsNamed) {
  const fs::path dir = scratch_dir("calibrate_glove_lib");
  const GloveTruth g = glove_truth(14);
  const GloveCapture flat = load_glove_csv(write(dir / "dflat.csv", glove_csv(g.flat, 1, 6)));
  const GloveCapture fist = load_glove_csv(write(dir / "dfist.csv", glove_csv(g.fist, 2, 6)));
  try {
    calibrate_glove(flat, fist);
    ADD_FAILURE() << "a dead sensor was accepted";
  } catch (const CalibrationError& e) {
    EXPECT_NE(std::string(e.what()).find("1 sensor moved less than 5 %"), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("sensor 6 (middle near knuckle)"), std::string::npos)
        << e.what();
  }
}

// ---- the command
// ---------------------------------------------------------------------------------

TEST(OperatorCalibrateCommand, BodyAndGloveWriteARigThatLoads) {
  TELEX_REQUIRE_BINARIES("telex");
  const fs::path dir = scratch_dir("calibrate_operator");
  const fs::path rig = dir / "rig.json";
  fs::remove(rig);
  write(rig, R"({"rig_version": 1, "operator": {"body": {"ipd_m": 0.066}, "bodies": {)"
             R"("right_hand": 2, "right_shoulder": 3, "left_hand": 5, "left_shoulder": 4,)"
             R"("right_elbow": 6, "left_elbow": 7}}})"
             "\n");
  TPose t;
  t.upper_arm_m = 0.32;
  t.forearm_m = 0.26;
  t.elbows = true;
  const fs::path csv = write(dir / "tpose.csv", tpose_csv(t));
  const CommandRun b = telex_calibrate(
      dir, "body", {"body", "--tracking", csv.string(), "--rig", rig.string(), "--json"});
  ASSERT_EQ(b.rc, 0) << b.err;
  const auto j = nlohmann::json::parse(b.out);
  EXPECT_EQ(j["from"], "elbow markers");
  EXPECT_EQ(j["samples"], 720);  // both sides
  EXPECT_NEAR(j["upper_arm_m"].get<double>(), 0.32, 0.005);
  EXPECT_NEAR(j["forearm_m"].get<double>(), 0.26, 0.005);
  EXPECT_LT(j["spread_m"].get<double>(), 0.01);
  EXPECT_TRUE(j["sides"].contains("left") && j["sides"].contains("right"));

  const GloveTruth g = glove_truth(5);
  const fs::path flat = write(dir / "flat.csv", glove_csv(g.flat, 3));
  const fs::path fist = write(dir / "fist.csv", glove_csv(g.fist, 4));
  const CommandRun gl = telex_calibrate(dir, "glove",
                                        {"glove", "--flat", flat.string(), "--fist", fist.string(),
                                         "--side", "left", "--out", rig.string(), "--json"});
  ASSERT_EQ(gl.rc, 0) << gl.err;
  const auto jg = nlohmann::json::parse(gl.out);
  EXPECT_EQ(jg["side"], "left");
  EXPECT_EQ(jg["sensors"], 5);
  ASSERT_EQ(jg["min"].size(), 5u);
  ASSERT_EQ(jg["max"].size(), 5u);

  const Rig r = load_rig(rig);
  EXPECT_NEAR(r.body.upper_arm_m, 0.32, 0.005);
  EXPECT_NEAR(r.body.forearm_m, 0.26, 0.005);
  EXPECT_EQ(r.bodies.left_elbow, 7);  // the rest of the file kept
  EXPECT_EQ(r.body.ipd_m, 0.066);
  ASSERT_TRUE(r.glove[0].has_value());
  EXPECT_FALSE(r.glove[1].has_value());
  for (int i = 0; i < 5; ++i) {
    EXPECT_NEAR(r.glove[0]->min[i], g.flat[i], 0.01) << i;
    EXPECT_NEAR(r.glove[0]->max[i], g.fist[i], 0.01) << i;
    EXPECT_EQ(r.glove[0]->min[i], jg["min"][i].get<double>());
  }
}

// Live: telex-sim-natnet plays a T-pose recording (NatNet's CSV: no valid column) over loopback.
TEST(OperatorCalibrateCommand, BodyOverLiveNatNet) {
  TELEX_REQUIRE_BINARIES("telex", "telex-sim-natnet");
  const fs::path dir = scratch_dir("calibrate_operator_natnet");
  TPose t;
  t.upper_arm_m = 0.31;
  t.forearm_m = 0.27;
  t.elbows = true;
  t.left = false;
  std::string recording = "time_s,body_id,x,y,z,qx,qy,qz,qw\n";
  std::istringstream rows(tpose_csv(t));
  std::string line;
  std::getline(rows, line);  // the --log-tracking header
  while (std::getline(rows, line)) recording += line.substr(0, line.rfind(',')) + "\n";
  const fs::path csv = write(dir / "natnet_tpose.csv", recording);
  const std::string port = std::to_string(free_port());
  Process sim({built_binary("telex-sim-natnet").string(), "--motion", csv.string(), "--bind",
               "127.0.0.1", "--command-port", port, "--duration", "30"},
              dir / "sim.out", dir / "sim.err");
  const fs::path rig = dir / "rig.json";
  fs::remove(rig);
  const CommandRun b =
      telex_calibrate(dir, "live",
                      {"body", "--natnet", "127.0.0.1,unicast,cmd=" + port, "--seconds", "2",
                       "--settle-s", "0.3", "--right-elbow", "6", "--out", rig.string(), "--json"});
  ASSERT_EQ(b.rc, 0) << b.err;
  EXPECT_NE(b.err.find("T-pose"), std::string::npos) << b.err;  // the prompt
  const auto j = nlohmann::json::parse(b.out);
  EXPECT_EQ(j["from"], "elbow markers");
  EXPECT_GE(j["samples"].get<int>(), 30);
  EXPECT_NEAR(j["upper_arm_m"].get<double>(), 0.31, 0.005);
  EXPECT_NEAR(j["forearm_m"].get<double>(), 0.27, 0.005);
  EXPECT_NEAR(load_rig(rig).body.forearm_m, 0.27, 0.005);
}

TEST(OperatorCalibrateCommand, FailuresExitOneAndBadFlagsTwo) {
  TELEX_REQUIRE_BINARIES("telex");
  const fs::path dir = scratch_dir("calibrate_operator_errors");
  const fs::path rig = dir / "rig.json";
  fs::remove(rig);
  TPose bent;
  bent.elbow_bend_rad = 40.0 * kPi / 180.0;
  const fs::path csv = write(dir / "bent.csv", tpose_csv(bent));
  const CommandRun b = telex_calibrate(dir, "bent",
                                       {"body", "--tracking", csv.string(), "--left-shoulder", "4",
                                        "--left-wrist", "5", "--out", rig.string()});
  EXPECT_EQ(b.rc, 1) << b.err;
  EXPECT_NE(b.err.find("right arm: the wrist is"), std::string::npos) << b.err;
  EXPECT_FALSE(fs::exists(rig));  // nothing written

  const CommandRun none = telex_calibrate(dir, "none", {"body", "--out", rig.string()});
  EXPECT_EQ(none.rc, 2);
  EXPECT_NE(none.err.find("--tracking"), std::string::npos) << none.err;

  const GloveTruth g = glove_truth(5);
  const fs::path flat = write(dir / "flat.csv", glove_csv(g.flat, 3, 2));
  const fs::path fist = write(dir / "fist.csv", glove_csv(g.fist, 4, 2));
  const CommandRun dead =
      telex_calibrate(dir, "dead",
                      {"glove", "--flat", flat.string(), "--fist", fist.string(), "--side", "right",
                       "--out", rig.string()});
  EXPECT_EQ(dead.rc, 1);
  EXPECT_NE(dead.err.find("sensor 2 (middle)"), std::string::npos) << dead.err;
  const CommandRun half = telex_calibrate(
      dir, "half", {"glove", "--flat", flat.string(), "--side", "right", "--out", rig.string()});
  EXPECT_EQ(half.rc, 2);
  EXPECT_NE(half.err.find("--fist"), std::string::npos) << half.err;
}

}  // namespace
}  // namespace telex::test
