// SPDX-License-Identifier: MIT
// TELEX_DEMAND stops the process with the file, line and condition, in every build type.
#include "telex/base/demand.h"

#include <gtest/gtest.h>

namespace telex {
namespace {

int checked_half(int even) {
  TELEX_DEMAND(even % 2 == 0);
  return even / 2;
}

TEST(DemandDeathTest, ABrokenPreconditionAbortsNamingFileLineAndCondition) {
  EXPECT_EQ(checked_half(4), 2);
  EXPECT_DEATH(checked_half(3), "demand_test.cpp:11: TELEX_DEMAND\\(even % 2 == 0\\) failed");
}

}  // namespace
}  // namespace telex
