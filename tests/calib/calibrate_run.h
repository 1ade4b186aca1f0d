// SPDX-License-Identifier: MIT
// `telex calibrate ARGS` as a process, for the calibration tests: its exit code and output.
#pragma once

#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <string>
#include <vector>

#include "process.h"
#include "test_support.h"

namespace telex::test {

struct CommandRun {
  int rc = -1;
  std::string out, err;
};

// Runs the built `telex calibrate` with `args`; its output goes to dir/NAME.out and .err.
inline CommandRun telex_calibrate(const std::filesystem::path& dir, const std::string& name,
                                  std::vector<std::string> args) {
  std::vector<std::string> argv{built_binary("telex").string(), "calibrate"};
  argv.insert(argv.end(), args.begin(), args.end());
  Process p(argv, dir / (name + ".out"), dir / (name + ".err"));
  const auto rc = p.wait(std::chrono::seconds(120));
  EXPECT_TRUE(rc.has_value()) << "telex calibrate " << name << " did not finish";
  return {rc.value_or(-1), p.stdout_text(), p.stderr_text()};
}

}  // namespace telex::test
