// SPDX-License-Identifier: MIT
// Test helpers: where the shared real frames are, and where built binaries live.
#pragma once

#include <csignal>
#include <exception>
#include <filesystem>
#include <initializer_list>
#include <string>

namespace telex::test {

// Directory ../shared/data/real beside the clone, or empty when this clone has none.
std::filesystem::path real_data_dir();

// Path of a binary built by this project (telex, telex-remote, telex-local, ...).
std::filesystem::path built_binary(const std::string& name);

// Runs built binary `name` with `args` (shell words; output discarded) and returns its exit code
// (-1 when it did not exit normally): the exit codes of bad flags and missing devices.
int exit_code_of(const std::string& name, const std::string& args);

// The names among `names` that this tree has not built, comma-separated ("" when all are).
std::string missing_binaries(std::initializer_list<const char*> names);

// The sanitizer builds run the daemons several times slower (ASan+UBSan on 2 cores: the remote
// sends 10-15 of its 30 frames a second, a full-frame surface arrives 140 ms after capture). The
// integration tests' throughput and latency bounds are scaled by this factor there; the plain
// build, which CI runs, is held to the bounds as written.
#ifdef TELEX_SANITIZER_BUILD
inline constexpr double kSanitizerSlowdown = 4.0;
#else
inline constexpr double kSanitizerSlowdown = 1.0;
#endif
// A process's resident memory says nothing of its own bounds under AddressSanitizer, whose
// quarantine keeps up to 256 MiB of freed blocks mapped: the memory bounds are checked in the
// plain build only (the sanitizer build checks the counters beside them).
#ifdef TELEX_SANITIZER_BUILD
inline constexpr bool kResidentMemoryMeaningful = false;
#else
inline constexpr bool kResidentMemoryMeaningful = true;
#endif

// Whether `rc` is the exit code of a process killed by `sig` (128 + sig). In the sanitizer
// builds a sanitizer's SEGV handler reports the crash and exits with its own code (ASan 1, TSan
// 66): the process still died, and any nonzero code counts.
inline bool died_by_signal(int rc, int sig) {
#ifdef TELEX_SANITIZER_BUILD
  if (sig == SIGSEGV) return rc != 0;
#endif
  return rc == 128 + sig;
}

// The last value of `name N` in a daemon's log (telex-remote's once-a-second stats lines print
// cumulative counters so), -1 when absent. `name` must stand as a word: "repaired" does not match
// inside "tiles-repaired".
long last_counter(const std::string& log_text, const std::string& name);

// What `f` throws, as its what(), or "(no exception)".
template <typename F>
std::string message_of(F&& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "(no exception)";
}

// A gtest expectation that `text` contains `part`, printing both when it does not.
void expect_contains(const std::string& text, const std::string& part);

// Whether skipping is forbidden: TELEX_NO_SKIPS=1 in the environment (.ci/run sets it, since CI
// has everything a test needs, so a skip there hides a broken setup).
bool skips_forbidden();

// The one way a test skips: with the reason it gives, when `condition` does not hold; a failure
// with that reason instead where skips are forbidden.
#define TELEX_SKIP_UNLESS(condition, reason)                           \
  do {                                                                 \
    if (!(condition)) {                                                \
      if (::telex::test::skips_forbidden())                            \
        FAIL() << "would skip, and TELEX_NO_SKIPS is set: " << reason; \
      GTEST_SKIP() << reason;                                          \
    }                                                                  \
  } while (0)

// Skips when the shared real frames are absent (present in CI beside the clone, absent in a
// user's).
#define TELEX_REQUIRE_REAL_DATA()                                                     \
  TELEX_SKIP_UNLESS(!::telex::test::real_data_dir().empty(),                          \
                    "shared real frames not found at " TELEX_SHARED_DIR               \
                    "/data/real (present in CI beside the clone; absent in a user's " \
                    "clone)")

// Skips when one of the named binaries was not built in this tree.
#define TELEX_REQUIRE_BINARIES(...)                                         \
  TELEX_SKIP_UNLESS(::telex::test::missing_binaries({__VA_ARGS__}).empty(), \
                    "not built in this tree: " << ::telex::test::missing_binaries({__VA_ARGS__}))

}  // namespace telex::test
