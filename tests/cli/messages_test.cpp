// SPDX-License-Identifier: MIT
// The small things a newcomer reads (issue 50, point 9): each message says what is valid, names
// the flag, suggests the nearest name or a spec of the right kind, and prints numbers as typed.
#include <gtest/gtest.h>

#include <chrono>
#include <fstream>
#include <string>
#include <vector>

#include "process.h"
#include "test_support.h"

namespace telex {
namespace {

using namespace std::chrono_literals;

using test::Outcome;
using test::run;

TEST(Messages, APositiveOnlyFlagStatesItsRangeTruly) {
  const Outcome o = run("telex", {"calibrate", "depth-eye", "--square-mm", "0"});
  EXPECT_EQ(o.exit_code, 2) << o.err;
  test::expect_contains(o.err, "--square-mm: 0 is out of range (valid: > 0)");
  EXPECT_EQ(o.err.find(">= 0"), std::string::npos) << o.err;
}

TEST(Messages, AMistypedNatNetMotionSuggestsTheNearestName) {
  const Outcome o = run("telex-sim-natnet", {"--motion", "pres", "--duration", "0.1"});
  EXPECT_EQ(o.exit_code, 2) << o.err;
  test::expect_contains(o.err, "--motion");
  test::expect_contains(o.err, "did you mean press?");
}

TEST(Messages, CalibrateGloveSuggestsAGloveSpecNotAHand) {
  const Outcome o =
      run("telex", {"calibrate", "glove", "--glove", "5dt-usb", "--sensors", "5", "--side", "right",
                    "--out", test::scratch_file("rig.json").string()});
  // Exit 1 (the device is missing), not 2: the flags are right.
  EXPECT_EQ(o.exit_code, 1) << "a 5DT glove is plugged in here? " << o.err;
  EXPECT_EQ(o.err.find("script:"), std::string::npos) << o.err;
  test::expect_contains(o.err, "5dt-serial:");
}

TEST(Messages, ATruncatedJsonConfigNamesLineAndColumn) {
  const auto file = test::scratch_file("truncated.json");
  std::ofstream(file) << "{\n  \"stiffness\": 500,\n";
  const Outcome o = run("telex-local", {"--config", file.string(), "--duration", "0.1"});
  EXPECT_EQ(o.exit_code, 2) << o.err;
  test::expect_contains(o.err, file.string() + " line 3, column 1:");
}

TEST(Messages, DuplicateDynamixelIdsAreRefused) {
  const Outcome o = run("telex-sim-dynamixel", {"--ids", "1,1,2", "--duration", "0.1"});
  EXPECT_EQ(o.exit_code, 2) << o.err;
  test::expect_contains(o.err, "--ids '1,1,2': id 1 is given twice");
}

TEST(Messages, NatNetSimulatorPrintsItsDurationAsTyped) {
  for (const auto& [typed, printed] :
       std::vector<std::pair<std::string, std::string>>{{"0.5", "for 0.5 s"}, {"1", "for 1 s"}}) {
    const Outcome o = run("telex-sim-natnet", {"--duration", typed, "--command-port", "0"});
    EXPECT_EQ(o.exit_code, 0) << o.err;
    test::expect_contains(o.err, printed);
    EXPECT_EQ(o.err.find(".000000"), std::string::npos) << o.err;
  }
}

}  // namespace
}  // namespace telex
