#include "autocal/io/tum_trajectory.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <iostream>
#include <iterator>
#include <string>

#include "autocal/common/error.h"
#include "io/io_test_data.h"
#include "io/prefix_check.h"
#include "support/test_paths.h"

namespace autocal {
namespace io {
namespace {

using ::testing::HasSubstr;

std::string OutPath(const std::string& name) { return (test::OutputDir("tum") / name).string(); }

void WriteText(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << text;
}

TEST(TumTrajectoryTest, RoundTripsPosesAndNanosecondStamps) {
  Trajectory trajectory = test_data::MakeDrive(2.0).trajectory;
  // Stamps that a double in seconds could not hold: epoch-sized with odd nanoseconds.
  for (size_t i = 0; i < trajectory.size(); ++i) trajectory[i].t_ns += static_cast<int64_t>(i % 7);
  WriteTumTrajectory(OutPath("drive.tum"), trajectory);
  const Trajectory read = ReadTumTrajectory(OutPath("drive.tum"));
  ASSERT_EQ(read.size(), trajectory.size());
  for (size_t i = 0; i < read.size(); ++i) {
    ASSERT_EQ(read[i].t_ns, trajectory[i].t_ns) << "pose " << i;
    ASSERT_EQ(read[i].T_W_I.p, trajectory[i].T_W_I.p) << "pose " << i;
    ASSERT_EQ(read[i].T_W_I.q.coeffs(), trajectory[i].T_W_I.q.coeffs()) << "pose " << i;
  }
  std::ifstream in(OutPath("drive.tum"));
  std::string header;
  std::getline(in, header);
  EXPECT_EQ(header, "# autocal_trajectory_1 timestamp tx ty tz qx qy qz qw");
}

TEST(TumTrajectoryTest, ReadsShorterDecimalsAndNegativeStamps) {
  WriteText(OutPath("short.tum"),
            "# comment\n-0.5 0 0 0 0 0 0 1\n1.25 1 2 3 0 0 0 1\n\n2 1 2 3 0 0 1 0\n");
  const Trajectory read = ReadTumTrajectory(OutPath("short.tum"));
  ASSERT_EQ(read.size(), 3u);
  EXPECT_EQ(read[0].t_ns, -500'000'000);
  EXPECT_EQ(read[1].t_ns, 1'250'000'000);
  EXPECT_EQ(read[2].t_ns, 2'000'000'000);
}

void ExpectParseError(const std::string& name, const std::string& text, int64_t line,
                      int64_t column, const std::string& message) {
  const std::string path = OutPath(name);
  WriteText(path, text);
  try {
    ReadTumTrajectory(path);
    ADD_FAILURE() << "no ParseError for\n" << text;
  } catch (const ParseError& e) {
    EXPECT_EQ(e.location().file, path);
    EXPECT_EQ(e.location().line, line) << e.what();
    EXPECT_EQ(e.location().column, column) << e.what();
    EXPECT_THAT(e.detail(), HasSubstr(message)) << e.what();
  }
}

// evo writes TUM files with numpy's default format, "%.18e": the stamps in scientific notation.
// They read exactly, to the nanosecond; digits finer than a nanosecond round to the nearest.
TEST(TumTrajectoryTest, ReadsScientificNotationAndRoundsToTheNanosecond) {
  WriteText(OutPath("evo.tum"),
            "1.403636579763555527e+09 4.688319000000000329e+00 -1.786938000000000031e+00 "
            "7.833379999999999876e-01 5.341940000000000055e-01 -1.530109999999999872e-01 "
            "-8.271969999999999523e-01 -8.245599999999999963e-02\n"
            "1.4036365798135555E9 0 0 0 0 0 0 1\n"
            "1403636580.8135555555 0 0 0 0 0 0 1\n"
            "14036365818135555554e-10 0 0 0 0 0 0 1\n"
            "+1.5e9 0 0 0 0 0 0 1\n");
  const Trajectory read = ReadTumTrajectory(OutPath("evo.tum"));
  ASSERT_EQ(read.size(), 5u);
  EXPECT_EQ(read[0].t_ns, 1403636579763555527);
  EXPECT_EQ(read[0].T_W_I.p.x(), 4.688319);
  EXPECT_EQ(read[1].t_ns, 1403636579813555500);
  EXPECT_EQ(read[2].t_ns, 1403636580813555556);  // ...555 5555: rounds up
  EXPECT_EQ(read[3].t_ns, 1403636581813555555);  // ...555 554: rounds down
  EXPECT_EQ(read[4].t_ns, 1'500'000'000'000'000'000);
  const std::string head = "1.0 0 0 0 0 0 0 1\n";
  ExpectParseError("exponent.tum", head + "2e 0 0 0 0 0 0 1\n", 2, 1, "expected a timestamp");
  ExpectParseError("huge.tum", "1e10 0 0 0 0 0 0 1\n", 1, 1, "does not fit in int64");
  ExpectParseError("point.tum", head + "2.0.0 0 0 0 0 0 0 1\n", 2, 1, "expected a timestamp");
}

TEST(TumTrajectoryTest, BadInput) {
  const std::string head = "# timestamp tx ty tz qx qy qz qw\n1.0 0 0 0 0 0 0 1\n";
  ExpectParseError("few.tum", head + "2.0 0 0 0 0 0 1\n", 3, 16, "expected 8 values");
  ExpectParseError("many.tum", head + "2.0 0 0 0 0 0 0 1 9\n", 3, 19, "found 9");
  ExpectParseError("nan.tum", head + "2.0 0 nan 0 0 0 0 1\n", 3, 7, "non-finite");
  ExpectParseError("stamp.tum", head + "2.0s 0 0 0 0 0 0 1\n", 3, 1, "expected a timestamp");
  ExpectParseError("duplicate.tum", head + "1.0 0 0 0 0 0 0 1\n", 3, 1, "duplicate timestamp");
  ExpectParseError("backwards.tum", head + "0.5 0 0 0 0 0 0 1\n", 3, 1, "non-monotonic timestamp");
  ExpectParseError("quaternion.tum", head + "2.0 0 0 0 0 0 0 2\n", 3, 11, "norm 2");
  // Seconds at the int64 edges: |INT64_MIN| does not exist, so the range check may not
  // take an absolute value.
  ExpectParseError("far_past.tum", "-9223372036854775808 0 0 0 0 0 0 1\n", 1, 1,
                   "does not fit in int64 nanoseconds");
  ExpectParseError("far_future.tum", "9223372036854775807 0 0 0 0 0 0 1\n", 1, 1,
                   "does not fit in int64 nanoseconds");
}

std::string FileBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// A written trajectory states that it is whole (first line, "# end: N poses" last): every
// proper prefix of it is refused, so a file cut mid-number or at a line break is never read
// as a shorter trajectory. Before, a trajectory cut at 8,192 bytes passed evaluation.
TEST(TumTrajectoryTest, EveryPrefixOfAWrittenTrajectoryIsRefused) {
  Trajectory trajectory = test_data::MakeDrive(2.0).trajectory;
  trajectory.resize(std::min<size_t>(trajectory.size(), 8));
  const std::string path = OutPath("whole.tum");
  WriteTumTrajectory(path, trajectory);
  const std::string bytes = FileBytes(path);
  EXPECT_THAT(bytes,
              ::testing::EndsWith("\n# end: " + std::to_string(trajectory.size()) + " poses\n"));
  ASSERT_EQ(ReadTumTrajectory(path).size(), trajectory.size());
  EXPECT_EQ(test_data::CountAcceptedPrefixes(bytes, OutPath("cut.tum"),
                                             [](const std::string& p) { ReadTumTrajectory(p); }),
            0u);
}

TEST(TumTrajectoryTest, AWrittenTrajectoryChecksItsEndLine) {
  const std::string head =
      "# autocal_trajectory_1 timestamp tx ty tz qx qy qz qw\n1.0 0 0 0 0 0 0 1\n";
  const std::string two = head + "2.0 0 0 0 0 0 0 1\n";
  WriteText(OutPath("whole2.tum"), two + "# end: 2 poses\n");
  EXPECT_EQ(ReadTumTrajectory(OutPath("whole2.tum")).size(), 2u);
  ExpectParseError("count.tum", two + "# end: 3 poses\n", 4, 1, "counts 3 poses");
  ExpectParseError("after_end.tum", head + "# end: 1 poses\n2.0 0 0 0 0 0 0 1\n", 4, 1,
                   "text after the end line");
  ExpectParseError("no_break.tum", two + "# end: 2 poses", 0, 0, "it was cut short");
  ExpectParseError("no_end.tum", two, 0, 0, "ends without its end line '# end: 2 poses'");
  // Another tool's file has no such lines; an empty one or one without poses is refused.
  ExpectParseError("empty.tum", "", 0, 0, "the file is empty");
  ExpectParseError("comments.tum", "# timestamp tx ty tz qx qy qz qw\n", 0, 0, "holds no poses");
}

}  // namespace
}  // namespace io
}  // namespace autocal
