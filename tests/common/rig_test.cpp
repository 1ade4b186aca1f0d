// SPDX-License-Identifier: MIT
// The rig file: defaults, the round trip, every error naming its key, merge updates, --rig in argv.
#include "telex/common/rig.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "process.h"

namespace telex {
namespace {

std::string error_of(const std::string& text) {
  try {
    parse_rig(text, "test.json");
  } catch (const RigError& e) {
    return e.what();
  }
  return "";
}

TEST(Rig, AnEmptyObjectIsTheBuiltInDefaults) {
  const Rig rig = parse_rig("{}", "test.json");
  const Rig def;
  EXPECT_FALSE(rig.depth);
  EXPECT_FALSE(rig.eye[0]);
  EXPECT_FALSE(rig.X_RightEyeLeftEye);
  EXPECT_FALSE(rig.baseline_m());
  EXPECT_EQ(rig.bodies.head, def.bodies.head);
  EXPECT_EQ(rig.bodies.right_hand, 2);
  EXPECT_EQ(rig.body.upper_arm_m, BodyDims{}.upper_arm_m);
  EXPECT_EQ(rig.p_HeadCamera, def.p_HeadCamera);
  EXPECT_EQ(rig.robot_head.joints[0].name, "yaw");
  EXPECT_TRUE(rig.gravity_grabber.is_null());
}

TEST(Rig, WhatItWritesItReadsBack) {
  Rig rig;
  rig.depth = Intrinsics{570.3, 570.3, 319.5, 239.5, 640, 480};
  rig.eye[0] = CameraModel{{530.0, 531.0, 322.0, 241.0, 640, 480}, {-0.1, 0.02, 0.001, 0.0, 0.0}};
  rig.eye[1] = CameraModel{{529.0, 530.5, 318.0, 238.0, 640, 480}, {-0.12, 0.03, 0.0, 0.002, 0.0}};
  rig.X_RightEyeLeftEye = RigidTransform{glm::dmat3(1.0), {0.065, 0.0, 0.001}};
  rig.X_RightEyeDepth = RigidTransform{glm::dmat3(1.0), {-0.025, 0.001, 0.0}};
  rig.bodies.left_hand = 4;
  rig.bodies.right_elbow = 7;
  rig.body.upper_arm_m = 0.30;
  rig.body.hands[1].fingers[1].segment_m = {0.05, 0.03, 0.02};
  rig.glove[1] = GloveRange{{0.1, 0.1, 0.1, 0.1, 0.1}, {0.9, 0.8, 0.9, 0.9, 0.7}};
  rig.display_channel[1] = {4, 3, 2, 1, 0};
  rig.skin_rgb = {90, 60, 40};
  rig.gravity_grabber = {{"max_pressure_N", 2.5}};
  rig.robot_head.joints[0].min_rad = -1.2;
  rig.robot_head.joints[2].max_accel_rad_s2 = 5.0;

  const Rig back = parse_rig(rig_to_json(rig).dump(), "round trip");
  ASSERT_TRUE(back.depth && back.eye[0] && back.eye[1]);
  EXPECT_EQ(*back.depth, *rig.depth);
  EXPECT_EQ(back.eye[0]->k, rig.eye[0]->k);
  EXPECT_EQ(back.eye[1]->distortion, rig.eye[1]->distortion);
  ASSERT_TRUE(back.baseline_m());
  EXPECT_NEAR(*back.baseline_m(), std::hypot(0.065, 0.001), 1e-12);
  EXPECT_EQ(back.X_RightEyeDepth->translation_m, rig.X_RightEyeDepth->translation_m);
  EXPECT_EQ(back.bodies.left_hand, 4);
  EXPECT_EQ(back.bodies.right_elbow, 7);
  EXPECT_EQ(back.body.upper_arm_m, 0.30);
  EXPECT_EQ(back.body.hands[1].fingers[1].segment_m, rig.body.hands[1].fingers[1].segment_m);
  EXPECT_TRUE(back.body.hands[0].left);
  EXPECT_EQ(back.glove[1]->max, rig.glove[1]->max);
  EXPECT_FALSE(back.glove[0]);
  EXPECT_EQ(back.display_channel[1], rig.display_channel[1]);
  EXPECT_EQ(back.skin_rgb, rig.skin_rgb);
  EXPECT_EQ(back.gravity_grabber, rig.gravity_grabber);
  EXPECT_NEAR(back.robot_head.joints[0].min_rad, -1.2, 1e-12);
  EXPECT_NEAR(back.robot_head.joints[2].max_accel_rad_s2, 5.0, 1e-12);
  EXPECT_EQ(back.R_CameraHead, rig.R_CameraHead);
}

TEST(Rig, EveryErrorNamesTheKeyAndWhatIsWrong) {
  struct Case {
    const char* text;
    const char* names;
  };
  const Case cases[] = {
      {R"({"eyes":{"left":{"width":640,"height":480,"fx_px":500,"fy_px":500,"cx_px":320,
           "cy_px":240,"fxx":1}}})",
       "eyes.left.fxx: unknown key"},
      {R"({"eyes":{"left":{"width":640,"height":480,"fx_px":"500","fy_px":500,"cx_px":320,
           "cy_px":240}}})",
       "eyes.left.fx_px: must be a number, got a string"},
      {R"({"eyes":{"middle":{}}})", "eyes.middle: unknown key"},
      {R"({"depth":{"width":640}})", "depth: needs width, height"},
      {R"({"operator":{"body":{"upper_arm_m":2.0}}})",
       "operator.body.upper_arm_m: must be within [0.1, 0.6], got 2"},
      {R"({"operator":{"bodies":{"head":1,"right_hand":1}}})",
       "head and right_hand are both body 1"},
      {R"({"operator":{"bodies":{"left_knee":5}}})", "operator.bodies.left_knee: unknown key"},
      {R"({"extrinsics":{"right_eye_from_left_eye":{"rotation":[[1,0,0],[0,1,0],[0,0.5,1]],
           "translation_m":[0.065,0,0]}}})",
       "extrinsics.right_eye_from_left_eye.rotation: is not a rotation"},
      {R"({"extrinsics":{"right_eye_from_left_eye":{"translation_m":[0,0,0]}}})",
       "at least 1 mm apart"},
      {R"({"eyes":{"right":{"width":640,"height":480,"fx_px":500,"fy_px":500,"cx_px":320,
           "cy_px":240,"distortion":[1,2,3]}}})",
       "eyes.right.distortion: must hold 4 to 5 numbers, got 3"},
      {R"({"robot_head":{"joints":[{},{},{"min_deg":10,"max_deg":5}]}})",
       "robot_head.joints[2]: max_deg must be above min_deg"},
      {R"({"robot_head":{"joints":[{}]}})", "robot_head.joints: must be an array of 3"},
      // Issue 27: a head beside people turns no faster than a person's head.
      {R"({"robot_head":{"joints":[{"max_rate_deg_s":3600},{},{}]}})",
       "robot_head.joints[0].max_rate_deg_s: must be within [1, 360], got 3600"},
      {R"({"robot_head":{"joints":[{},{"max_accel_deg_s2":0},{}]}})",
       "robot_head.joints[1].max_accel_deg_s2: must be within [1, 7200], got 0"},
      {R"({"operator":{"gloves":{"right":{"min":[0,0,0,0,0],"max":[1,1,0,1,1]}}}})",
       "operator.gloves.right: sensor 2 has max <= min"},
      {R"({"operator":{"gloves":{"right":{"min":[0,0,0,0,0,0],"max":[1,1,1,1,1,1]}}}})",
       "must both hold 5 or 14"},
      {R"({"operator":{"display_channels":{"right":[0,1,1,3,4]}}})",
       "fingers 1 and 2 both drive channel 1"},
      {R"({"rig_version":2})", "rig_version: this build reads version 1, got 2"},
      {R"({"gravity_grabber":3})", "gravity_grabber: must be an object"},
      {R"([1,2])", "top level: must be an object"},
      {R"({"depth": )", "not JSON"},
      {R"({"speed":1})", "speed: unknown key (known here: rig_version, depth, eyes"},
  };
  for (const Case& c : cases) {
    const std::string e = error_of(c.text);
    EXPECT_NE(e.find("rig test.json: "), std::string::npos) << c.text << "\n -> " << e;
    EXPECT_NE(e.find(c.names), std::string::npos) << c.text << "\n -> " << e;
  }
}

TEST(Rig, AMissingFileNamesItsPath) {
  try {
    load_rig("/nonexistent/lab/rig.json");
    FAIL() << "no error";
  } catch (const RigError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/lab/rig.json: no such file"),
              std::string::npos)
        << e.what();
  }
}

TEST(Rig, UpdatesMergeIntoTheFileAndNeverWriteABadRig) {
  const auto dir = ::telex::test::scratch_dir("rig");
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const auto path = dir / "rig.json";

  update_rig_file(path, {{"operator", {{"bodies", {{"left_hand", 5}}}}}});  // creates it
  update_rig_file(
      path,
      {{"eyes",
        {{"right", camera_model_json({{500, 501, 320, 240, 640, 480}, {0.1, 0, 0, 0, 0}})}}}});
  Rig rig = load_rig(path);
  EXPECT_EQ(rig.bodies.left_hand, 5);  // kept by the second update
  ASSERT_TRUE(rig.eye[1]);
  EXPECT_EQ(rig.eye[1]->k.fy, 501);
  EXPECT_EQ(rig.path, path);

  std::ifstream before_in(path);
  const std::string before((std::istreambuf_iterator<char>(before_in)), {});
  EXPECT_THROW(update_rig_file(path, {{"operator", {{"bodies", {{"head", 5}}}}}}), RigError);
  std::ifstream after_in(path);
  const std::string after((std::istreambuf_iterator<char>(after_in)), {});
  EXPECT_EQ(before, after);
  std::filesystem::remove_all(dir);
}

TEST(Rig, TheExampleInTheDocsLoads) {
  const Rig rig = load_rig(std::filesystem::path(TELEX_SOURCE_DIR) / "docs" / "rig-example.json");
  ASSERT_TRUE(rig.eye[0] && rig.eye[1] && rig.depth && rig.X_RightEyeDepth);
  ASSERT_TRUE(rig.baseline_m());
  EXPECT_GT(*rig.baseline_m(), 0.05);
}

TEST(Rig, TheRigFlagIsFoundBeforeTheOthersAreParsed) {
  {
    const char* argv[] = {"x", "--view", "none", "--rig", "a.json", "--duration", "1"};
    EXPECT_EQ(rig_path_in_args(7, argv), std::filesystem::path("a.json"));
  }
  {
    const char* argv[] = {"x", "--rig=b.json"};
    EXPECT_EQ(rig_path_in_args(2, argv), std::filesystem::path("b.json"));
  }
  {
    const char* argv[] = {"x", "--view", "none"};
    EXPECT_FALSE(rig_path_in_args(3, argv));
  }
  {
    const char* argv[] = {"x", "--rig"};
    EXPECT_THROW(rig_path_in_args(2, argv), RigError);
  }
  {
    const char* argv[] = {"x", "--rig", "--view"};
    EXPECT_THROW(rig_path_in_args(3, argv), RigError);
  }
}

}  // namespace
}  // namespace telex
