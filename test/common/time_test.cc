#include "autocal/common/time.h"

#include <gtest/gtest.h>

namespace autocal {
namespace {

// Every nanosecond survives, for epoch stamps and for stamps before zero, where an integer
// quotient and remainder would print "-0.-000000001".
TEST(FormatSeconds, PrintsAllNineDecimals) {
  EXPECT_EQ(FormatSeconds(1'700'000'000'123'456'789), "1700000000.123456789");
  EXPECT_EQ(FormatSeconds(1'700'000'000'000'000'001), "1700000000.000000001");
  EXPECT_EQ(FormatSeconds(0), "0.000000000");
  EXPECT_EQ(FormatSeconds(-1), "-0.000000001");
  EXPECT_EQ(FormatSeconds(-1'500'000'000), "-1.500000000");
}

}  // namespace
}  // namespace autocal
