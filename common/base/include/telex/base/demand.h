// SPDX-License-Identifier: MIT
// The first of two error tiers, as Drake's DRAKE_DEMAND: a broken precondition is a bug in the
// caller, so the process stops at once, with the file, line and condition, in every build type.
// Bad input (a file, a flag, a packet) is the second tier: an exception at start-up or a status
// value in a running loop, never this.
#pragma once

namespace telex::detail {
[[noreturn]] void demand_failed(const char* condition, const char* file, int line) noexcept;
}  // namespace telex::detail

#define TELEX_DEMAND(condition)                                       \
  do {                                                                \
    if (!(condition)) [[unlikely]]                                    \
      ::telex::detail::demand_failed(#condition, __FILE__, __LINE__); \
  } while (0)
