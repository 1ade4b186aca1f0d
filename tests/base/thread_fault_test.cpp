// SPDX-License-Identifier: MIT
// ThreadFault: a thread body's exception is kept and counted instead of terminating the process.
#include "telex/base/thread_fault.h"

#include <gtest/gtest.h>

#include <stdexcept>
#include <thread>

namespace telex {
namespace {

TEST(ThreadFault, AThrowingThreadIsCaughtCountedAndReportedWithItsName) {
  ThreadFault fault("tracking (telex-natnet)");
  EXPECT_FALSE(fault.failed());
  EXPECT_FALSE(fault.report().has_value());
  // Without the catch this thread's exception would call std::terminate and end the test binary.
  std::thread t([&] { fault.run([] { throw std::runtime_error("bad pose"); }); });
  t.join();
  ASSERT_TRUE(fault.failed());
  EXPECT_EQ(fault.count(), 1u);
  const auto r = fault.report();
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->thread, "tracking (telex-natnet)");
  EXPECT_EQ(r->what(), "bad pose");
  // A later failure is counted; the first error stays the one reported.
  EXPECT_FALSE(fault.run([] { throw 42; }));
  EXPECT_EQ(fault.count(), 2u);
  EXPECT_EQ(fault.report()->what(), "bad pose");
}

TEST(ThreadFault, NonStandardExceptionsAreNamedAndACleanBodyIsNoFault) {
  ThreadFault fault("display writer");
  EXPECT_TRUE(fault.run([] {}));
  EXPECT_FALSE(fault.failed());
  EXPECT_FALSE(fault.run([] { throw 7; }));
  EXPECT_EQ(fault.report()->what(), "unknown exception (not derived from std::exception)");
}

}  // namespace
}  // namespace telex
