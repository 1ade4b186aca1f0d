// SPDX-License-Identifier: MIT
// EyePairer: pairs within tolerance, drops and counts the rest, never pairs across a stall.
#include "telex/video/eye_pairer.h"

#include <gtest/gtest.h>

namespace telex::video {
namespace {

constexpr std::int64_t kPeriodNs = 33'333'333;  // 30 Hz

TEST(EyePairer, DefaultToleranceIsHalfAFramePeriod) {
  EXPECT_EQ(EyePairer<int>(kPeriodNs).tolerance_ns(), kPeriodNs / 2);
  EXPECT_EQ(EyePairer<int>(kPeriodNs, 1000).tolerance_ns(), 1000);
}

TEST(EyePairer, PairsFramesWithinToleranceInEitherOrder) {
  EyePairer<int> pairer(kPeriodNs);
  EXPECT_FALSE(pairer.push(Eye::Left, 1, 1'000'000));
  auto pair = pairer.push(Eye::Right, 2, 1'000'000 + 5'000'000);
  ASSERT_TRUE(pair);
  EXPECT_EQ(pair->left, 1);
  EXPECT_EQ(pair->right, 2);
  EXPECT_EQ(pair->capture_ns, 1'000'000);  // the older eye's
  EXPECT_EQ(pair->skew_ns, 5'000'000);
  // Right first this time, left later: still left and right in their places.
  EXPECT_FALSE(pairer.push(Eye::Right, 4, 40'000'000));
  pair = pairer.push(Eye::Left, 3, 43'000'000);
  ASSERT_TRUE(pair);
  EXPECT_EQ(pair->left, 3);
  EXPECT_EQ(pair->right, 4);
  EXPECT_EQ(pair->capture_ns, 40'000'000);
  EXPECT_EQ(pair->skew_ns, -3'000'000);
  EXPECT_EQ(pairer.counters().pairs, 2u);
  EXPECT_EQ(pairer.counters().unpaired_left + pairer.counters().unpaired_right, 0u);
}

TEST(EyePairer, ToleranceBoundaryIsInclusive) {
  EyePairer<int> pairer(kPeriodNs, 1000);
  pairer.push(Eye::Left, 1, 10'000);
  EXPECT_TRUE(pairer.push(Eye::Right, 2, 11'000));
  pairer.push(Eye::Left, 3, 20'000);
  EXPECT_FALSE(pairer.push(Eye::Right, 4, 21'001));  // 1 ns too far: the left is dropped
  EXPECT_EQ(pairer.counters().unpaired_left, 1u);
  EXPECT_EQ(pairer.waiting(Eye::Right), 1u);  // the right waits for a left near it
  EXPECT_TRUE(pairer.push(Eye::Left, 5, 21'500));
}

TEST(EyePairer, DropsAndCountsUnpairedFramesOfEachEye) {
  EyePairer<int> pairer(kPeriodNs);
  // Left at 30 Hz; right skips its second frame (a dropped USB frame).
  const std::int64_t l[] = {0, kPeriodNs, 2 * kPeriodNs, 3 * kPeriodNs};
  const std::int64_t r[] = {2'000'000, 2 * kPeriodNs + 2'000'000, 3 * kPeriodNs + 2'000'000};
  int pairs = 0;
  pairs += pairer.push(Eye::Left, 0, l[0]).has_value();
  pairs += pairer.push(Eye::Right, 0, r[0]).has_value();
  pairs += pairer.push(Eye::Left, 1, l[1]).has_value();
  pairs += pairer.push(Eye::Left, 2, l[2]).has_value();
  auto pair = pairer.push(Eye::Right, 2, r[1]);
  ASSERT_TRUE(pair);
  EXPECT_EQ(pair->left, 2);  // not left 1, which no right frame matched
  pairs += 1;
  pairs += pairer.push(Eye::Right, 3, r[2]).has_value();
  pairs += pairer.push(Eye::Left, 3, l[3]).has_value();
  EXPECT_EQ(pairs, 3);
  EXPECT_EQ(pairer.counters().pairs, 3u);
  EXPECT_EQ(pairer.counters().unpaired_left, 1u);
  EXPECT_EQ(pairer.counters().unpaired_right, 0u);
}

TEST(EyePairer, AStalledEyeCostsAtMostTheWaitingBound) {
  EyePairer<int> pairer(kPeriodNs, -1, 3);
  for (int i = 0; i < 10; ++i) EXPECT_FALSE(pairer.push(Eye::Left, i, i * kPeriodNs));
  EXPECT_EQ(pairer.waiting(Eye::Left), 3u);
  EXPECT_EQ(pairer.counters().unpaired_left, 7u);
  // The right eye comes back: it pairs with the left frame of its instant, the older are dropped.
  auto pair = pairer.push(Eye::Right, 100, 9 * kPeriodNs + 1000);
  ASSERT_TRUE(pair);
  EXPECT_EQ(pair->left, 9);
  EXPECT_EQ(pairer.counters().unpaired_left, 9u);
  EXPECT_EQ(pairer.waiting(Eye::Left), 0u);
}

TEST(EyePairer, OutOfOrderFramesDroppedAndCounted) {
  EyePairer<int> pairer(kPeriodNs);
  pairer.push(Eye::Left, 1, 5 * kPeriodNs);
  EXPECT_FALSE(pairer.push(Eye::Left, 2, 4 * kPeriodNs));
  EXPECT_FALSE(pairer.push(Eye::Left, 3, 5 * kPeriodNs));  // a repeat is not newer
  EXPECT_EQ(pairer.counters().out_of_order, 2u);
  EXPECT_EQ(pairer.waiting(Eye::Left), 1u);
  auto pair = pairer.push(Eye::Right, 9, 5 * kPeriodNs);
  ASSERT_TRUE(pair);
  EXPECT_EQ(pair->left, 1);
}

}  // namespace
}  // namespace telex::video
