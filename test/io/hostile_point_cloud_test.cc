// PLY and PCD files crafted to break a reader: repeated header keys, declared sizes that
// wrap size_t or int64, element counts no file could hold, numbers beyond the float range.
// Each must give one ParseError naming the file, the place and what was expected (no
// crash, no hang, no silent infinity). The overflow helpers behind the size checks are
// tested at their boundaries.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/io/point_cloud_file.h"
#include "io/byte_source.h"
#include "io/checked_math.h"
#include "support/test_paths.h"

namespace autocal {
namespace io {
namespace {

using ::testing::HasSubstr;

constexpr int64_t kInt64Max = std::numeric_limits<int64_t>::max();
constexpr int64_t kInt64Min = std::numeric_limits<int64_t>::min();
constexpr size_t kSizeMax = std::numeric_limits<size_t>::max();

std::string WriteFile(const std::string& name, const std::string& bytes) {
  const std::string path = (test::OutputDir("hostile_point_cloud") / name).string();
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  return path;
}

// Reads `bytes` written as `name` and returns the one ParseError it must raise.
ParseError ReadError(const std::string& name, const std::string& bytes,
                     const PointCloudReadOptions& options = {}) {
  const std::string path = WriteFile(name, bytes);
  try {
    ReadPointCloudFile(path, options);
  } catch (const ParseError& e) {
    EXPECT_EQ(e.location().file, path);
    return e;
  }
  ADD_FAILURE() << "no ParseError for " << name;
  return ParseError(SourceLocation{}, "none");
}

template <typename T>
std::string Bytes(T value) {
  std::string out(sizeof(T), '\0');
  std::memcpy(out.data(), &value, sizeof(T));
  return out;
}

// ---- checked arithmetic ----

TEST(CheckedMathTest, AddAtTheBoundaries) {
  using internal::CheckedAdd;
  size_t s = 0;
  EXPECT_TRUE(CheckedAdd(kSizeMax - 1, size_t{1}, &s));
  EXPECT_EQ(s, kSizeMax);
  EXPECT_FALSE(CheckedAdd(kSizeMax, size_t{1}, &s));
  EXPECT_FALSE(CheckedAdd(kSizeMax / 2 + 1, kSizeMax / 2 + 1, &s));
  int64_t i = 0;
  EXPECT_TRUE(CheckedAdd(kInt64Max - 3, int64_t{3}, &i));
  EXPECT_EQ(i, kInt64Max);
  EXPECT_FALSE(CheckedAdd(kInt64Max - 2, int64_t{3}, &i));
  EXPECT_TRUE(CheckedAdd(kInt64Min, kInt64Max, &i));
  EXPECT_EQ(i, -1);
  EXPECT_FALSE(CheckedAdd(kInt64Min, int64_t{-1}, &i));
}

TEST(CheckedMathTest, MultiplyAtTheBoundaries) {
  using internal::CheckedMultiply;
  size_t s = 0;
  EXPECT_TRUE(CheckedMultiply(kSizeMax / 8, size_t{8}, &s));
  EXPECT_EQ(s, kSizeMax / 8 * 8);
  EXPECT_FALSE(CheckedMultiply(kSizeMax / 8 + 1, size_t{8}, &s));
  EXPECT_FALSE(CheckedMultiply(size_t{1} << 32, size_t{1} << 32, &s));  // wraps to 0
  EXPECT_TRUE(CheckedMultiply(kSizeMax, size_t{0}, &s));
  EXPECT_EQ(s, 0u);
  int64_t i = 0;
  EXPECT_TRUE(CheckedMultiply(int64_t{3037000499}, int64_t{3037000499}, &i));
  EXPECT_FALSE(CheckedMultiply(int64_t{3037000500}, int64_t{3037000500}, &i));
  EXPECT_FALSE(CheckedMultiply(kInt64Min, int64_t{-1}, &i));
  EXPECT_TRUE(CheckedMultiply(kInt64Min, int64_t{1}, &i));
}

// The read position cannot leave the file, whatever a reader computes.
TEST(ByteSourceTest, PositionStaysInsideTheFile) {
  const std::string path = "f.bin";
  const std::string bytes = "abcde";
  internal::ByteSource source(path, bytes);
  source.Advance(5);
  EXPECT_EQ(source.remaining(), 0u);
  source.set_pos(2);
  try {
    source.Advance(kSizeMax);
    ADD_FAILURE() << "Advance past the end";
  } catch (const ParseError& e) {
    EXPECT_EQ(e.location().file, path);
    EXPECT_EQ(e.location().byte_offset, 5);
    EXPECT_THAT(e.detail(), HasSubstr("after byte 2: truncated?"));
  }
  EXPECT_EQ(source.pos(), 2u);
  EXPECT_THROW(source.set_pos(6), ParseError);
  EXPECT_EQ(source.pos(), 2u);
}

// ---- PCD ----

const char kPcdHeaderKeys[][10] = {"VERSION", "FIELDS", "SIZE",   "TYPE",     "COUNT",
                                   "WIDTH",   "HEIGHT", "POINTS", "VIEWPOINT"};

// Each header key twice: the second is refused where it stands, naming the first.
TEST(HostilePcdTest, RepeatedHeaderKeyIsRefused) {
  const std::vector<std::string> lines = {"VERSION 0.7", "FIELDS x y z", "SIZE 4 4 4",
                                          "TYPE F F F",  "COUNT 1 1 1",  "WIDTH 1",
                                          "HEIGHT 1",    "POINTS 1",     "VIEWPOINT 0 0 0 1 0 0 0"};
  for (size_t k = 0; k < lines.size(); ++k) {
    SCOPED_TRACE(kPcdHeaderKeys[k]);
    std::string text;
    for (size_t i = 0; i < lines.size(); ++i) {
      text += lines[i] + "\n";
      if (i == k) text += "  " + lines[i] + "\n";
    }
    text += "DATA ascii\n1 2 3\n";
    const ParseError e = ReadError("repeated_key.pcd", text);
    EXPECT_EQ(e.location().line, static_cast<int64_t>(k) + 2);
    EXPECT_EQ(e.location().column, 3);
    EXPECT_THAT(e.detail(), HasSubstr("second '" + std::string(kPcdHeaderKeys[k]) + "' line"));
    EXPECT_THAT(e.detail(), HasSubstr("the first is line " + std::to_string(k + 1)));
  }
}

// The fuzzer's case: a second FIELDS line with more fields than SIZE and TYPE describe
// (read past the end of the SIZE words).
TEST(HostilePcdTest, SecondFieldsLineAfterSizeAndType) {
  const ParseError e = ReadError(
      "fields_twice.pcd",
      "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nFIELDS x y z a b c\nWIDTH 1\nDATA ascii\n1 2 3\n");
  EXPECT_EQ(e.location().line, 4);
  EXPECT_EQ(e.location().column, 1);
  EXPECT_THAT(e.detail(), HasSubstr("second 'FIELDS' line in the PCD header"));
}

// COUNT x SIZE wraps size_t to 0 (2^61 doubles) or the record offset wraps.
TEST(HostilePcdTest, RecordSizeBeyondSizeTIsRefused) {
  for (const std::string count : {"2305843009213693952", "2305843009213693951"}) {
    SCOPED_TRACE(count);
    const ParseError e =
        ReadError("huge_record.pcd", "FIELDS x y z n\nSIZE 4 4 4 8\nTYPE F F F F\nCOUNT 1 1 1 " +
                                         count + "\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA binary\n" +
                                         std::string(64, '\0'));
    EXPECT_EQ(e.location().line, 4);
    EXPECT_EQ(e.location().column, 13);
    EXPECT_THAT(e.detail(), HasSubstr("COUNT " + count + " of field 'n'"));
    EXPECT_THAT(e.detail(), HasSubstr("point record larger than"));
  }
}

// COUNT values whose sum (values per ascii line) passes int64.
TEST(HostilePcdTest, CountSumBeyondInt64IsRefused) {
  const ParseError e = ReadError("count_sum.pcd",
                                 "FIELDS x y z a b\nSIZE 4 4 4 4 4\nTYPE F F F F F\n"
                                 "COUNT 1 1 1 9223372036854775800 9\nWIDTH 1\nDATA ascii\n"
                                 "1 2 3 4 5\n");
  EXPECT_EQ(e.location().line, 4);
  EXPECT_EQ(e.location().column, 33);
  EXPECT_THAT(e.detail(), HasSubstr("COUNT values add up to more than 9223372036854775807"));
}

// A large but representable COUNT in an ascii file: the line cannot hold the values.
TEST(HostilePcdTest, LargeAsciiCountReportsTheValueCount) {
  const ParseError e = ReadError("large_count.pcd",
                                 "FIELDS x y z a\nSIZE 4 4 4 4\nTYPE F F F F\n"
                                 "COUNT 1 1 1 2305843009213693952\nWIDTH 1\nDATA ascii\n"
                                 "1 2 3 4\n");
  EXPECT_EQ(e.location().line, 7);
  EXPECT_THAT(e.detail(), HasSubstr("expected 2305843009213693955 values, found 4"));
}

// An ascii point is a line of at least x, y and z: a count the bytes cannot hold is refused
// before the points are allocated (it let a 100 MB file allocate 3.6 GB, a byte a point).
TEST(HostilePcdTest, AsciiCountBeyondWhatTheBytesHold) {
  std::string padding;
  for (int i = 0; i < 1000; ++i) padding += "1\n";
  const ParseError e = ReadError("many_points.pcd",
                                 "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
                                 "WIDTH 1000\nDATA ascii\n" +
                                     padding);
  EXPECT_THAT(e.detail(), HasSubstr("the header declares 1000 points: truncated?"));
}

TEST(HostilePcdTest, IntensityBeyondFloatRange) {
  PointCloudReadOptions drop;
  drop.drop_non_finite_points = true;
  const std::string header = "FIELDS x y z intensity\nSIZE 4 4 4 8\nTYPE F F F F\nWIDTH 2\n";
  const std::string ascii = header + "DATA ascii\n1 2 3 4\n1 2 3 -1e39\n";
  const std::string binary = header + "DATA binary\n" + Bytes(1.0f) + Bytes(2.0f) + Bytes(3.0f) +
                             Bytes(1e300) + Bytes(1.0f) + Bytes(2.0f) + Bytes(3.0f) + Bytes(4.0);
  for (const PointCloudReadOptions& options : {PointCloudReadOptions{}, drop}) {
    ParseError e = ReadError("big_intensity.pcd", ascii, options);
    EXPECT_EQ(e.location().line, 7);
    EXPECT_THAT(e.detail(), HasSubstr("point 1 has intensity -1e+39, outside the range of a"));
    e = ReadError("big_intensity.pcd", binary, options);
    // Record 0 starts right after the DATA line.
    EXPECT_EQ(e.location().byte_offset, static_cast<int64_t>(header.size() + 12));
    EXPECT_THAT(e.detail(), HasSubstr("point 0 has intensity 1e+300, outside the range of a"));
  }
}

// ---- PLY ----

// An element without properties but with a huge count before `vertex` (the skip loop
// made no progress and ran 10^18 times).
TEST(HostilePlyTest, ElementWithoutPropertiesAndACount) {
  for (const std::string format : {"ascii", "binary_little_endian", "binary_big_endian"}) {
    SCOPED_TRACE(format);
    const ParseError e =
        ReadError("empty_element.ply", "ply\nformat " + format +
                                           " 1.0\nelement junk 1000000000000000000\n"
                                           "element vertex 1\nproperty float x\nproperty float y\n"
                                           "property float z\nend_header\n1 2 3\n");
    EXPECT_EQ(e.location().line, 3);
    EXPECT_EQ(e.location().column, 14);
    EXPECT_THAT(e.detail(), HasSubstr("element 'junk' has no properties but a count of "
                                      "1000000000000000000 (expected 0)"));
  }
}

// An element without properties and count 0 is harmless.
TEST(HostilePlyTest, ElementWithoutPropertiesAndCountZeroReads) {
  const std::string path =
      WriteFile("empty_element_zero.ply",
                "ply\nformat ascii 1.0\nelement junk 0\nelement vertex 1\nproperty float x\n"
                "property float y\nproperty float z\nend_header\n1 2 3\n");
  EXPECT_EQ(ReadPointCloudFile(path).size(), 1);
}

// A skipped element whose count the rest of the file cannot hold.
TEST(HostilePlyTest, SkippedElementCountBeyondTheFile) {
  for (const std::string format : {"ascii", "binary_little_endian"}) {
    SCOPED_TRACE(format);
    const std::string text = "ply\nformat " + format +
                             " 1.0\nelement junk 1000000000000000000\nproperty uchar a\n"
                             "element vertex 1\nproperty float x\nproperty float y\n"
                             "property float z\nend_header\n";
    const ParseError e = ReadError("huge_element.ply", text + "1 2 3\n");
    EXPECT_EQ(e.location().byte_offset, static_cast<int64_t>(text.size() + 6));
    EXPECT_THAT(e.detail(), HasSubstr("declares 1000000000000000000 junk instances needing at "
                                      "least 1 bytes each after byte " +
                                      std::to_string(text.size())));
  }
}

// Points after the last element's declared count (a writer that never updated "element vertex
// N") are refused where they start, not dropped; blank lines after an ascii body are fine.
TEST(HostilePlyTest, DataAfterTheDeclaredVertices) {
  const std::string binary_header =
      "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\n"
      "property float y\nproperty float z\nend_header\n";
  const std::string record = Bytes(1.0f) + Bytes(2.0f) + Bytes(3.0f);
  ParseError e = ReadError("extra_binary.ply", binary_header + record + record);
  EXPECT_EQ(e.location().byte_offset, static_cast<int64_t>(binary_header.size() + 12));
  EXPECT_THAT(e.detail(), HasSubstr("12 bytes of data after the 1 vertex instances the header "
                                    "declares (element vertex 1)"));
  const std::string ascii_header =
      "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
      "property float z\nend_header\n";
  e = ReadError("extra_ascii.ply", ascii_header + "1 2 3\n4 5 6\n");
  EXPECT_EQ(e.location().line, 9);
  EXPECT_EQ(e.location().column, 1);
  EXPECT_THAT(e.detail(), HasSubstr("data after the 1 vertex instances"));
  EXPECT_EQ(ReadPointCloudFile(WriteFile("blank_tail.ply", ascii_header + "1 2 3\n\n  \n")).size(),
            1);
}

// The fuzzer's case: a double intensity of 1e300 would have become float infinity.
TEST(HostilePlyTest, IntensityBeyondFloatRange) {
  const std::string header =
      "ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\n"
      "property float y\nproperty float z\nproperty double intensity\nend_header\n";
  const std::string record = Bytes(1.0f) + Bytes(2.0f) + Bytes(3.0f);
  ParseError e =
      ReadError("big_intensity.ply", header + record + Bytes(7.0) + record + Bytes(1e300));
  EXPECT_EQ(e.location().byte_offset, static_cast<int64_t>(header.size() + 20));
  EXPECT_THAT(e.detail(), HasSubstr("vertex 1 has intensity 1e+300, outside the range of a float"));

  e = ReadError("big_intensity_ascii.ply",
                "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                "property float z\nproperty float intensity\nend_header\n1 2 3 -3.5e38\n");
  EXPECT_EQ(e.location().line, 9);
  EXPECT_THAT(e.detail(), HasSubstr("vertex 0 has intensity -3.5e+38"));
}

// The float limit itself is stored; x, y, z and time are doubles, so any finite double
// is kept, and a number beyond the double range is refused where it is written.
TEST(HostilePlyTest, FloatLimitAndLargeCoordinatesRead) {
  const std::string header =
      "ply\nformat ascii 1.0\nelement vertex 1\nproperty double x\nproperty float y\n"
      "property float z\nproperty double intensity\nproperty double t\nend_header\n";
  const lidar::PointCloud cloud = ReadPointCloudFile(
      WriteFile("float_limit.ply", header + "1e300 2 3 3.4028234663852886e38 -0.5\n"));
  ASSERT_EQ(cloud.size(), 1);
  EXPECT_EQ(cloud.points(0, 0), 1e300);
  EXPECT_EQ(cloud.intensity[0], std::numeric_limits<float>::max());
  EXPECT_EQ(cloud.time_s[0], -0.5);
  // A time is a time within one sweep (lidar::kMaxPointTimeS), whatever a double can hold.
  EXPECT_THAT(ReadError("far_time.ply", header + "1 2 3 4 -1e300\n").detail(),
              HasSubstr("vertex 0 has time -1e+300 (a floating point property: seconds), not a "
                        "time within one sweep"));

  const ParseError e = ReadError("beyond_double.ply", header + "1 2 3 4 1e400\n");
  EXPECT_EQ(e.location().line, 10);
  EXPECT_EQ(e.location().column, 9);
  EXPECT_THAT(e.detail(), HasSubstr("out of the range of a double"));
}

}  // namespace
}  // namespace io
}  // namespace autocal
