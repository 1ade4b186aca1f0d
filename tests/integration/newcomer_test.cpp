// SPDX-License-Identifier: MIT
// What a newcomer types after the demo (issue 50): the README's "Running the nodes" example, and
// the daemons with no flags at all, touch the scene they are shown.
#include <gtest/gtest.h>

#include <chrono>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "daemons.h"
#include "process.h"
#include "test_support.h"

namespace telex::test {
namespace {

using namespace std::chrono_literals;

// Long enough for the scripted press to reach the surface (it starts 0.3 m short of it at
// 0.1 m/s) and hold; shorter than the README's run, which goes on until stopped.
constexpr const char* kDuration = "9";

double peak_pressure_of(Process& local) {
  EXPECT_EQ(local.wait(60s), 0) << local.stderr_text();
  const nlohmann::json j = summary_of(local);
  if (!j.is_object() || !j.contains("peak_pressure_N")) {
    ADD_FAILURE() << "no JSON summary: " << local.stdout_text() << local.stderr_text();
    return 0.0;
  }
  return j["peak_pressure_N"].get<double>();
}

// README.md, "Running the nodes", as written (the files in this test's folder, a duration and the
// JSON summary added).
TEST(Newcomer, ReadmeRunningTheNodesExampleTouchesTheScene) {
  const auto dir = scratch_dir("readme_example");
  RemoteProcess remote(dir, {"--source", "synthetic:moving"});
  Process local({built_binary("telex-local").string(),
                 "--connect",
                 "127.0.0.1:" + std::to_string(remote.port),
                 "--hand",
                 "script:press",
                 "--haptics",
                 "sim",
                 "--stiffness",
                 "500",
                 "--max-force",
                 "5",
                 "--log-forces",
                 (dir / "forces.csv").string(),
                 "--view",
                 "png:" + (dir / "view").string(),
                 "--print-forces",
                 "10",
                 "--duration",
                 kDuration,
                 "--json-summary"},
                dir / "local.out", dir / "local.err");
  EXPECT_GT(peak_pressure_of(local), 1.0)
      << "the scripted fingertip never pressed into the scene:\n"
      << local.stderr_text();
}

// Both daemons with their defaults: telex-remote's source (synthetic:moving, animated) and
// telex-local's hand (script:press) and display (sim). Only the port, the duration and the
// summary are given.
TEST(Newcomer, DaemonsWithNoFlagsTouchTheScene) {
  const auto dir = scratch_dir("no_flags");
  RemoteProcess remote(dir, {});
  Process local(
      {built_binary("telex-local").string(), "--connect",
       "127.0.0.1:" + std::to_string(remote.port), "--duration", kDuration, "--json-summary"},
      dir / "local.out", dir / "local.err");
  EXPECT_GT(peak_pressure_of(local), 1.0)
      << "the scripted fingertip never pressed into the scene:\n"
      << local.stderr_text();
}

}  // namespace
}  // namespace telex::test
