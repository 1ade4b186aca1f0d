// SPDX-License-Identifier: MIT
// What every `telex calibrate` subcommand shares: the bad-flag error (exit 2), the check that an
// existing --out is a rig, and the exit-code guard.
#pragma once

#include <cstdio>
#include <filesystem>
#include <stdexcept>
#include <string>

#include "telex/common/rig.h"

namespace telex::tool {

// A bad flag value (exit 2); everything else that stops a calibration exits 1.
class FlagError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

// An existing --out must be a rig already (checked before the slow part, so a typo in the file
// name of another JSON file costs no calibration run).
inline void check_out(const std::string& out) {
  std::error_code ec;
  if (!std::filesystem::exists(out, ec)) return;
  try {
    load_rig(out);
  } catch (const RigError& e) {
    throw FlagError(std::string(e.what()) + " (--out updates a rig file in place)");
  }
}

// Runs a subcommand: FlagError exits 2, any other error 1, each named.
template <typename F>
int guarded(const char* name, F&& f) {
  try {
    return f();
  } catch (const FlagError& e) {
    std::fprintf(stderr, "telex calibrate %s: error: %s\n", name, e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "telex calibrate %s: error: %s\n", name, e.what());
    return 1;
  }
}

}  // namespace telex::tool
