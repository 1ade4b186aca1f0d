// SPDX-License-Identifier: MIT
// The forked-child runner of the OpenNI tests (tests/support/driver_child.h): it retries only a
// crash inside OpenNI2 with no failure before it; a crash in project code, a failure followed by
// a crash, and a plain failure are reported as they are.
#include "driver_child.h"

#include <OniCAPI.h>
#include <gtest/gtest.h>

#include <cstdlib>
#include <stdexcept>

namespace telex::test {
namespace {

// Project code that dereferences a null pointer (opaque to the optimiser).
__attribute__((noinline)) void write_through(volatile int* p) { *p = 42; }
volatile int* volatile g_null = nullptr;

TEST(DriverChild, ACrashInProjectCodeIsNotTheDriver) {
  const ChildRun r = run_in_child([] { write_through(g_null); }, "OpenNI2");
#ifdef TELEX_SANITIZER_BUILD
  // UBSan reports the null store and exits with 1 before the fault: a failure, never retried.
  EXPECT_TRUE(r.end == ChildEnd::CrashedElsewhere || r.end == ChildEnd::Failed) << r.describe();
#else
  EXPECT_EQ(r.end, ChildEnd::CrashedElsewhere) << r.describe();
  EXPECT_NE(r.signal, 0);
  EXPECT_EQ(r.crash_object.find("OpenNI2"), std::string::npos) << r.crash_object;
#endif
}

TEST(DriverChild, ACrashInsideOpenNi2IsTheDriver) {
  // OpenNI2's C API dereferences the device handle without a check: a fault inside libOpenNI2.
  const ChildRun r = run_in_child(
      [] {
        OniDeviceInfo info;
        oniDeviceGetInfo(nullptr, &info);
      },
      "OpenNI2");
  EXPECT_EQ(r.end, ChildEnd::CrashedInDriver) << r.describe();
  EXPECT_NE(r.crash_object.find("libOpenNI2"), std::string::npos) << r.crash_object;
}

TEST(DriverChild, AFailureBeforeADriverCrashIsAFailure) {
  const ChildRun r = run_in_child(
      [] {
        ADD_FAILURE() << "expected failure inside the child (this test checks it is reported)";
        OniDeviceInfo info;
        oniDeviceGetInfo(nullptr, &info);
      },
      "OpenNI2");
  EXPECT_EQ(r.end, ChildEnd::Failed) << r.describe();
  EXPECT_NE(r.signal, 0);
}

TEST(DriverChild, ExitsAreReportedAsPassedOrFailed) {
  EXPECT_EQ(run_in_child([] {}, "OpenNI2").end, ChildEnd::Passed);
  EXPECT_EQ(
      run_in_child([] { ADD_FAILURE() << "expected failure inside the child"; }, "OpenNI2").end,
      ChildEnd::Failed);
  // An exception escaping the body is its failure, and the child does not run on into the suite.
  EXPECT_EQ(run_in_child([] { throw std::runtime_error("escaped"); }, "OpenNI2").end,
            ChildEnd::Failed);
  // abort() in project code: a crash outside the driver.
  EXPECT_EQ(run_in_child([] { std::abort(); }, "OpenNI2").end, ChildEnd::CrashedElsewhere);
}

}  // namespace
}  // namespace telex::test
