// SPDX-License-Identifier: MIT
// The newest-wins mailbox: replacing an unconsumed value counts a drop, take() times out.
#include "telex/base/latest_slot.h"

#include <gtest/gtest.h>

#include <chrono>
#include <thread>

namespace telex {
namespace {

using namespace std::chrono_literals;

TEST(LatestSlot, NewestWinsAndDropsAreCounted) {
  LatestSlot<int> slot;
  slot.put(1);
  slot.put(2);
  slot.put(3);
  EXPECT_EQ(slot.dropped(), 2u);
  auto v = slot.take(10ms);
  ASSERT_TRUE(v);
  EXPECT_EQ(*v, 3);
  EXPECT_FALSE(slot.take(1ms).has_value());
  EXPECT_EQ(slot.put_count(), 3u);
}

TEST(LatestSlot, ConsumerWakesOnPutFromAnotherThread) {
  LatestSlot<int> slot;
  std::thread producer([&] {
    std::this_thread::sleep_for(5ms);
    slot.put(42);
  });
  auto v = slot.take(5s);
  producer.join();
  ASSERT_TRUE(v);
  EXPECT_EQ(*v, 42);
}

TEST(LatestSlot, CloseReleasesWaiter) {
  LatestSlot<int> slot;
  std::thread closer([&] {
    std::this_thread::sleep_for(5ms);
    slot.close();
  });
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_FALSE(slot.take(10s).has_value());
  closer.join();
  EXPECT_LT(std::chrono::steady_clock::now() - t0, 5s);
}

}  // namespace
}  // namespace telex
