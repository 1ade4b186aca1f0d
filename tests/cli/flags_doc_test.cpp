// SPDX-License-Identifier: MIT
// docs/FLAGS.md is what `telex flags --markdown` prints now: a renamed flag or a changed default
// fails here until the file is regenerated (the command is in the message).
#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "process.h"
#include "test_support.h"

namespace telex {
namespace {

using namespace std::chrono_literals;

// `telex flags --markdown` alone: the programs beside telex (both daemons, the simulators) join
// its own flags.
TEST(FlagsDoc, CheckedInFileIsCurrent) {
  // Defaults must not depend on who runs the test.
  unsetenv("TELEX_REAL_DESK_DIR");
  test::Process proc({test::built_binary("telex").string(), "flags", "--markdown"},
                     test::scratch_file("flags.md"), test::scratch_file("err.txt"));
  ASSERT_EQ(proc.wait(60s).value_or(-1), 0) << proc.stderr_text();
  const std::string generated = proc.stdout_text();
  const std::string checked_in =
      test::read_text(std::filesystem::path(TELEX_SOURCE_DIR) / "docs" / "FLAGS.md");
  EXPECT_EQ(generated, checked_in) << "docs/FLAGS.md is out of date; regenerate it with\n  "
                                      "build/tools/telex flags --markdown > docs/FLAGS.md";
  for (const char* program : {"telex-remote", "telex-local", "telex-sim-natnet",
                              "telex-sim-dynamixel", "telex-sim-impair"})
    EXPECT_NE(generated.find(std::string("\n## ") + program + "\n"), std::string::npos)
        << program << " is missing from `telex flags --markdown`";
}

}  // namespace
}  // namespace telex
