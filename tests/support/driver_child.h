// SPDX-License-Identifier: MIT
// Runs a test body in a forked child and says how it ended: passed, failed an expectation, or
// crashed, and if it crashed, in which shared object and whether an expectation had failed first.
// For tests of third-party drivers with crashes of their own (OpenNI2's Dummy and OniFile), so a
// retry can be limited to crashes inside the driver.
#pragma once

#include <functional>
#include <string>

namespace telex::test {

enum class ChildEnd {
  Passed,            // exit 0, no failure
  Failed,            // an expectation failed (whether or not it then crashed)
  CrashedInDriver,   // a signal, no failure before it, inside an object matching the marker
  CrashedElsewhere,  // a signal, no failure before it, in any other object (project code)
};

struct ChildRun {
  ChildEnd end = ChildEnd::Failed;
  int signal = 0;            // the signal that killed the child, 0 if it exited
  std::string crash_object;  // shared object of the innermost frame outside the C/C++ runtime
  std::string describe() const;
};

// Forks; the child installs handlers for SIGSEGV, SIGBUS, SIGFPE, SIGILL and SIGABRT that report
// the crash's object (the faulting instruction's, or the innermost caller's outside libc,
// libstdc++, libgcc and the loader) through a pipe, runs `body` and exits with 1 if any
// expectation failed. A crash counts as in the driver when its object's path contains
// `driver_marker`.
ChildRun run_in_child(const std::function<void()>& body, const std::string& driver_marker);

// Runs `body` with run_in_child and reports it as the current test: a failure or a crash outside
// the driver fails the test at once; a crash inside OpenNI2 (its library or its drivers) is
// recorded as the test property driver_crash_N (what, where) and printed, and the body is run
// again, up to kMaxDriverRetries times, after which the test fails.
inline constexpr int kMaxDriverRetries = 2;
void run_driver_test(const std::function<void()>& body);

}  // namespace telex::test
