// SPDX-License-Identifier: MIT
// Test helpers: where the shared real frames are, and where built binaries live.
#pragma once

#include <filesystem>
#include <string>

namespace telex::test {

// Directory ../shared/data/real beside the clone, or empty when this clone has none.
std::filesystem::path real_data_dir();

// Skips the calling test with a clear message when the shared real frames are absent.
#define TELEX_REQUIRE_REAL_DATA()                                                              \
  do {                                                                                         \
    if (::telex::test::real_data_dir().empty())                                                \
      GTEST_SKIP() << "shared real frames not found at " TELEX_SHARED_DIR                      \
                      "/data/real (present in CI beside the clone; absent in a user's clone)"; \
  } while (0)

// Path of a binary built by this project (telex, telex-remote, telex-local, ...).
std::filesystem::path built_binary(const std::string& name);

}  // namespace telex::test
