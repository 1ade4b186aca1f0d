// SPDX-License-Identifier: MIT
// Test helpers: where the shared real frames are, and where built binaries live.
#include "test_support.h"

#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cctype>
#include <cstdlib>

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
  // A plain scan, not std::regex: GCC 12 with ASan warns inside libstdc++'s regex
  // (-Wmaybe-uninitialized), which -Werror would make the sanitizer build's failure.
  const std::string key = name + " ";
  long v = -1;
  for (std::size_t at = log_text.find(key); at != std::string::npos;
       at = log_text.find(key, at + 1)) {
    if (at > 0) {
      const char before = log_text[at - 1];
      if (std::isalnum(static_cast<unsigned char>(before)) || before == '_' || before == '-')
        continue;  // inside a longer name
    }
    std::size_t digits = at + key.size();
    long value = 0;
    bool any = false;
    while (digits < log_text.size() && std::isdigit(static_cast<unsigned char>(log_text[digits]))) {
      value = value * 10 + (log_text[digits++] - '0');
      any = true;
    }
    if (any) v = value;
  }
  return v;
}

void expect_contains(const std::string& text, const std::string& part) {
  EXPECT_NE(text.find(part), std::string::npos) << "'" << part << "' not in: " << text;
}

}  // namespace telex::test
