#include "autocal/common/error.h"

#include <gtest/gtest.h>

#include "autocal/common/time.h"

namespace autocal {
namespace {

TEST(ParseError, MessageNamesFileLineAndColumn) {
  const ParseError error({"imu.csv", 17, 3}, "expected a number, found 'abc'");
  EXPECT_STREQ(error.what(), "imu.csv:17:3: expected a number, found 'abc'");
  EXPECT_EQ(error.detail(), "expected a number, found 'abc'");
  EXPECT_EQ(error.location().line, 17);
}

TEST(ParseError, BinaryFilesUseByteOffsets) {
  SourceLocation location;
  location.file = "sweep.ply";
  location.byte_offset = 1024;
  EXPECT_EQ(location.ToString(), "sweep.ply: byte 1024");
}

TEST(Time, SecondsBetweenKeepsNanosecondsAtEpochScale) {
  const int64_t t0 = 1'700'000'000'000'000'000;
  EXPECT_DOUBLE_EQ(SecondsBetween(t0, t0 + 1), 1e-9);
  EXPECT_EQ(SecondsToNs(1.5), 1'500'000'000);
}

}  // namespace
}  // namespace autocal
