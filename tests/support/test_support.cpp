// SPDX-License-Identifier: MIT
// Test helpers: where the shared real frames are, and where built binaries live.
#include "test_support.h"

#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdlib>
#include <regex>

namespace telex::test {

std::filesystem::path real_data_dir() {
  std::filesystem::path p = std::filesystem::path(TELEX_SHARED_DIR) / "data" / "real";
  std::error_code ec;
  if (std::filesystem::is_directory(p, ec)) return p;
  return {};
}

bool skips_forbidden() {
  const char* v = std::getenv("TELEX_NO_SKIPS");
  return v && *v && std::string(v) != "0";
}

std::filesystem::path built_binary(const std::string& name) {
  std::filesystem::path p = std::filesystem::path(TELEX_BINARY_DIR) / "tools" / name;
  return p;
}

int exit_code_of(const std::string& name, const std::string& args) {
  const std::string cmd = built_binary(name).string() + " " + args + " >/dev/null 2>&1";
  const int rc = std::system(cmd.c_str());
  return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

std::string missing_binaries(std::initializer_list<const char*> names) {
  std::string missing;
  for (const char* n : names)
    if (!std::filesystem::exists(built_binary(n)))
      missing += (missing.empty() ? "" : ", ") + std::string(n);
  return missing;
}

long last_counter(const std::string& log_text, const std::string& name) {
  const std::regex re("(?:^|[^A-Za-z0-9_-])" + name + " ([0-9]+)");
  long v = -1;
  for (auto it = std::sregex_iterator(log_text.begin(), log_text.end(), re);
       it != std::sregex_iterator(); ++it)
    v = std::stol((*it)[1]);
  return v;
}

void expect_contains(const std::string& text, const std::string& part) {
  EXPECT_NE(text.find(part), std::string::npos) << "'" << part << "' not in: " << text;
}

}  // namespace telex::test
