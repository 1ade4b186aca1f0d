// SPDX-License-Identifier: MIT
// `telex warp --check --json` end to end: the issue's five keys in their order, the warp within
// half a degree where the lag alone gives about 4.8, and bad flags exit 2 naming themselves.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "process.h"
#include "test_support.h"

namespace telex {
namespace {

struct ToolRun {
  int exit_code = -1;
  std::string out, err;
};

ToolRun run_telex(const std::string& args) {
  const auto bin = test::built_binary("telex");
  EXPECT_TRUE(std::filesystem::exists(bin)) << bin << " not built";
  const std::filesystem::path err_file = test::scratch_file("warp_check_stderr.txt");
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

TEST(WarpCheckTool, PrintsTheIssuesKeysWithTheWarpWithinHalfADegree) {
  // The check's geometry at a smaller size than its 1280x720 default: the bounds are angular.
  const ToolRun r = run_telex("warp --check --json --eye-size 640x360 --frames 6");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::ordered_json::parse(r.out);
  std::vector<std::string> keys;
  for (const auto& [key, value] : j.items()) keys.push_back(key);
  EXPECT_EQ(keys, (std::vector<std::string>{"yaw_deg_s", "lag_ms", "error_deg_with",
                                            "error_deg_without", "warp_ms_per_eye"}));
  EXPECT_EQ(r.out.rfind("{\"yaw_deg_s\":60,\"lag_ms\":80,", 0), 0u) << r.out;
  EXPECT_LE(j["error_deg_with"].get<double>(), 0.5);
  EXPECT_GE(j["error_deg_without"].get<double>(), 4.0);
  EXPECT_LE(j["error_deg_without"].get<double>(), 6.0);
  EXPECT_GT(j["warp_ms_per_eye"].get<double>(), 0.0);
}

// --pair-gap-ms adds its case after the issue's five keys: the pair's own pose against the depth's.
TEST(WarpCheckTool, APairGapAddsTheDepthPoseErrorAfterTheFiveKeys) {
  const ToolRun r = run_telex("warp --check --json --eye-size 640x360 --frames 3 --pair-gap-ms 20");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::ordered_json::parse(r.out);
  std::vector<std::string> keys;
  for (const auto& [key, value] : j.items()) keys.push_back(key);
  EXPECT_EQ(keys,
            (std::vector<std::string>{"yaw_deg_s", "lag_ms", "error_deg_with", "error_deg_without",
                                      "warp_ms_per_eye", "pair_gap_ms", "error_deg_depth_pose"}));
  EXPECT_EQ(j["pair_gap_ms"].get<double>(), 20.0);
  EXPECT_LE(j["error_deg_with"].get<double>(), 0.5);
  EXPECT_GE(j["error_deg_depth_pose"].get<double>(), j["error_deg_with"].get<double>() + 0.6);
  const ToolRun bad = run_telex("warp --check --pair-gap-ms -5");
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find("--pair-gap-ms"), std::string::npos) << bad.err;
}

TEST(WarpCheckTool, WithoutLagThereIsNothingToCorrect) {
  const ToolRun r = run_telex("warp --check --json --eye-size 320x180 --frames 3 --lag-ms 0");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_LE(j["error_deg_without"].get<double>(), 0.2);
  EXPECT_LE(j["error_deg_with"].get<double>(), 0.2);
}

TEST(WarpCheckTool, BadFlagsExitTwoNamingTheFlag) {
  const ToolRun size = run_telex("warp --check --eye-size 640by360");
  EXPECT_EQ(size.exit_code, 2);
  EXPECT_NE(size.err.find("--eye-size"), std::string::npos) << size.err;
  const ToolRun nothing = run_telex("warp");
  EXPECT_EQ(nothing.exit_code, 2);
  EXPECT_NE(nothing.err.find("--check"), std::string::npos) << nothing.err;
}

}  // namespace
}  // namespace telex
