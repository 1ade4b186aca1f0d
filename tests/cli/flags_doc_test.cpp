// SPDX-License-Identifier: MIT
// docs/FLAGS.md is what `telex flags --markdown` prints now: a renamed flag or a changed default
// fails here until the file is regenerated (the command is in the message).
#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "process.h"
#include "test_support.h"

namespace telex {
namespace {

using namespace std::chrono_literals;

// The programs whose flags the table holds, besides telex's own.
const std::vector<std::string> kPrograms = {"telex-remote", "telex-local", "telex-sim-natnet",
                                            "telex-sim-dynamixel", "telex-sim-impair"};

TEST(FlagsDoc, CheckedInFileIsCurrent) {
  // Defaults must not depend on who runs the test.
  unsetenv("TELEX_REAL_DESK_DIR");
  std::vector<std::string> argv = {test::built_binary("telex").string(), "flags", "--markdown"};
  std::string regenerate = "build/tools/telex flags --markdown";
  for (const auto& p : kPrograms) {
    argv.push_back("--program");
    argv.push_back(test::built_binary(p).string());
    regenerate += " --program build/tools/" + p;
  }
  test::Process proc(argv, test::scratch_file("flags.md"), test::scratch_file("err.txt"));
  ASSERT_EQ(proc.wait(60s).value_or(-1), 0) << proc.stderr_text();
  const std::string generated = proc.stdout_text();
  const std::string checked_in =
      test::read_text(std::filesystem::path(TELEX_SOURCE_DIR) / "docs" / "FLAGS.md");
  EXPECT_EQ(generated, checked_in)
      << "docs/FLAGS.md is out of date; regenerate it with\n  " << regenerate << " > docs/FLAGS.md";
}

}  // namespace
}  // namespace telex
