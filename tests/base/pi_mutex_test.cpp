// SPDX-License-Identifier: MIT
// PiMutex: made with priority inheritance, and a mutex (two threads, one counter).
#include "telex/base/pi_mutex.h"

#include <gtest/gtest.h>

#include <condition_variable>
#include <mutex>
#include <thread>

namespace telex {
namespace {

TEST(PiMutex, IsMadeWithPriorityInheritance) {
  PiMutex m;
  EXPECT_EQ(m.protocol(), PTHREAD_PRIO_INHERIT);
}

TEST(PiMutex, ExcludesAndWorksWithLockGuardsAndConditionVariables) {
  PiMutex m;
  long counter = 0;
  auto add = [&] {
    for (int i = 0; i < 100'000; ++i) {
      std::lock_guard lock(m);
      ++counter;
    }
  };
  std::thread a(add), b(add);
  a.join();
  b.join();
  EXPECT_EQ(counter, 200'000);
  ASSERT_TRUE(m.try_lock());
  std::thread other([&] { EXPECT_FALSE(m.try_lock()); });
  other.join();
  m.unlock();
  std::condition_variable_any cv;
  bool ready = false;
  std::thread waker([&] {
    std::lock_guard lock(m);
    ready = true;
    cv.notify_one();
  });
  {
    std::unique_lock lock(m);
    cv.wait(lock, [&] { return ready; });
  }
  waker.join();
  EXPECT_TRUE(ready);
}

}  // namespace
}  // namespace telex
