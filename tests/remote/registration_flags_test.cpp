// SPDX-License-Identifier: MIT
// --registration hardware|rig|none: the one registration of a run over every way extrinsics can
// arrive (none, the rig in IR or colour pixels, --register), the combinations that would register
// twice refused naming both, and telex-remote saying which ran on its stats line.
#include <gtest/gtest.h>

#include <chrono>
#include <fstream>
#include <string>
#include <vector>

#include "flags.h"
#include "process.h"
#include "test_support.h"

namespace telex::remote {
namespace {

using namespace std::chrono_literals;

Rig rig_in(DepthPixels pixels) {
  Rig rig;
  rig.path = "head.json";
  rig.X_RightEyeDepth = RigidTransform{glm::dmat3(1.0), {-0.03, 0.045, 0.0}};
  rig.depth_pixels = pixels;
  return rig;
}

struct Outcome {
  DepthRegistration registration = DepthRegistration::None;
  RegisterMode stage = RegisterMode::None;
  bool hardware = false;
  std::string error;  // empty: accepted
};

// The flags' registration (`register_mode` as --register gave it, "" when not given), the rig,
// then --registration `asked` over `source`.
Outcome choose(std::string_view asked, std::string_view register_mode, const Rig* rig,
               std::string_view source = "openni:") {
  RegistrationConfig reg = parse_registration(register_mode.empty() ? "none" : register_mode,
                                              "0.025,0,0", "0,0,0", "", 1.0);
  const bool given = !register_mode.empty() && register_mode != "none";
  if (rig) apply_rig(*rig, {!register_mode.empty(), false, false, false}, reg);
  SourceOptions options;
  Outcome o;
  try {
    o.registration = choose_registration({asked, given, rig, source}, reg, options);
  } catch (const std::invalid_argument& e) {
    o.error = e.what();
    return o;
  }
  o.stage = reg.mode;
  o.hardware = options.hardware_registration;
  return o;
}

TEST(Registration, EachModeRunsExactlyOneRegistration) {
  const Rig ir = rig_in(DepthPixels::Ir), colour = rig_in(DepthPixels::Color);
  // Not asked: rig when there are extrinsics, else none; the sensor's own registration stays off.
  auto o = choose("", "", nullptr);
  EXPECT_EQ(o.registration, DepthRegistration::None);
  EXPECT_FALSE(o.hardware);
  o = choose("", "", &ir);
  EXPECT_EQ(o.registration, DepthRegistration::Rig);
  EXPECT_EQ(o.stage, RegisterMode::Full);
  EXPECT_FALSE(o.hardware) << "IR-pixel extrinsics need the sensor's own pixels";
  o = choose("", "shift", nullptr, "synthetic");
  EXPECT_EQ(o.registration, DepthRegistration::Rig);
  EXPECT_EQ(o.stage, RegisterMode::Shift);

  // hardware: the sensor registers, the stage does nothing.
  o = choose("hardware", "", nullptr);
  ASSERT_EQ(o.error, "");
  EXPECT_EQ(o.registration, DepthRegistration::Hardware);
  EXPECT_EQ(o.stage, RegisterMode::None);
  EXPECT_TRUE(o.hardware);
  o = choose("hardware", "", &colour);  // colour-pixel extrinsics are not applied on their own
  ASSERT_EQ(o.error, "");
  EXPECT_EQ(o.stage, RegisterMode::None);
  EXPECT_TRUE(o.hardware);

  // rig: the extrinsics, in the sensor's own pixels; colour-pixel ones after the sensor's.
  o = choose("rig", "", &ir);
  ASSERT_EQ(o.error, "");
  EXPECT_EQ(o.registration, DepthRegistration::Rig);
  EXPECT_EQ(o.stage, RegisterMode::Full);
  EXPECT_FALSE(o.hardware);
  o = choose("rig", "", &colour);
  ASSERT_EQ(o.error, "");
  EXPECT_EQ(o.stage, RegisterMode::Full);
  EXPECT_TRUE(o.hardware);
  o = choose("rig", "full", nullptr, "synthetic");
  ASSERT_EQ(o.error, "");
  EXPECT_EQ(o.stage, RegisterMode::Full);
  EXPECT_FALSE(o.hardware);

  // none: neither, whatever the rig holds.
  o = choose("none", "", &ir);
  ASSERT_EQ(o.error, "");
  EXPECT_EQ(o.registration, DepthRegistration::None);
  EXPECT_EQ(o.stage, RegisterMode::None);
  EXPECT_FALSE(o.hardware);
}

TEST(Registration, ACombinationThatWouldRegisterTwiceIsRefusedNamingBoth) {
  const Rig ir = rig_in(DepthPixels::Ir);
  auto o = choose("hardware", "", &ir);
  EXPECT_NE(o.error.find("--registration hardware and the rig's extrinsics.right_eye_from_depth "
                         "(depth_pixels \"ir\", head.json) would register twice"),
            std::string::npos)
      << o.error;
  o = choose("hardware", "full", nullptr);
  EXPECT_NE(o.error.find("--registration hardware and --register full would register twice"),
            std::string::npos)
      << o.error;
  o = choose("none", "shift", nullptr);
  EXPECT_NE(o.error.find("--registration none and --register shift contradict"), std::string::npos)
      << o.error;
  o = choose("rig", "", nullptr);
  EXPECT_NE(o.error.find("--registration rig needs extrinsics"), std::string::npos) << o.error;
  o = choose("hardware", "", nullptr, "synthetic:plane");
  EXPECT_NE(o.error.find("--registration hardware: source 'synthetic:plane' has no sensor "
                         "registration"),
            std::string::npos)
      << o.error;
  const Rig colour = rig_in(DepthPixels::Color);
  o = choose("rig", "", &colour, "files:x_*.png");
  EXPECT_NE(o.error.find("source 'files:x_*.png' has no sensor registration"), std::string::npos)
      << o.error;
}

struct RemoteRun {
  int rc = -1;
  std::string err;
};

RemoteRun run_remote(const std::filesystem::path& dir, std::vector<std::string> args,
                     const std::string& name) {
  std::vector<std::string> argv{test::built_binary("telex-remote").string(), "--listen",
                                "127.0.0.1:0"};
  argv.insert(argv.end(), args.begin(), args.end());
  test::Process p(argv, dir / (name + ".out"), dir / (name + ".err"));
  const auto rc = p.wait(60s);
  EXPECT_TRUE(rc.has_value()) << name << ": telex-remote did not finish";
  return {rc.value_or(-1), p.stderr_text()};
}

TEST(Registration, TheRemoteRefusesTwiceWithExit2AndSaysWhichRanOnItsStatsLine) {
  TELEX_REQUIRE_BINARIES("telex-remote");
  const auto dir = test::scratch_dir("registration_remote");
  const auto rig = dir / "head.json";
  std::ofstream(rig) << R"({"rig_version": 1, "extrinsics": {"depth_pixels": "ir",
      "right_eye_from_depth": {"rotation": [[1,0,0],[0,1,0],[0,0,1]],
                               "translation_m": [-0.03, 0.045, 0.0]}}})";
  auto r = run_remote(dir,
                      {"--rig", rig.string(), "--source", "openni:Dummy", "--registration",
                       "hardware", "--duration", "1"},
                      "twice_rig");
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_NE(r.err.find("--registration hardware and the rig's extrinsics.right_eye_from_depth"),
            std::string::npos)
      << r.err;
  r = run_remote(dir,
                 {"--source", "openni:Dummy", "--registration", "hardware", "--register", "full",
                  "--duration", "1"},
                 "twice_flags");
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_NE(r.err.find("--registration hardware and --register full would register twice"),
            std::string::npos)
      << r.err;
  // OpenNI2's Dummy device has no hardware registration: named at start.
  r = run_remote(dir, {"--source", "openni:Dummy", "--registration", "hardware", "--duration", "1"},
                 "dummy_hardware");
  EXPECT_EQ(r.rc, 1) << r.err;
  EXPECT_NE(r.err.find("OpenNI2 device 'Dummy' offers no depth-to-colour registration"),
            std::string::npos)
      << r.err;
  // The rig's extrinsics run as rig; the stats line says so, as it says none without them.
  r = run_remote(dir, {"--rig", rig.string(), "--source", "synthetic:plane", "--duration", "2.5"},
                 "rig");
  EXPECT_EQ(r.rc, 0) << r.err;
  EXPECT_NE(r.err.find("| registration rig"), std::string::npos) << r.err;
  r = run_remote(dir, {"--source", "synthetic:plane", "--duration", "2.5"}, "none");
  EXPECT_EQ(r.rc, 0) << r.err;
  EXPECT_NE(r.err.find("| registration none"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace telex::remote
