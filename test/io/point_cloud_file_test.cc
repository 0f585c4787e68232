#include "autocal/io/point_cloud_file.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "autocal/common/error.h"
#include "io/point_cloud_formats.h"
#include "support/test_paths.h"

namespace autocal {
namespace io {
namespace {

using ::testing::HasSubstr;

std::string OutPath(const std::string& name) {
  return (test::OutputDir("point_cloud_file") / name).string();
}

void WriteBytes(const std::string& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

// A sweep with values that float represents exactly, so a write/read round trip must be
// bit exact: points on a helix sampled on a 1/64 m grid, intensity ramp, time ramp.
lidar::PointCloud HelixCloud(int n) {
  lidar::PointCloud cloud;
  cloud.points.resize(3, n);
  cloud.intensity.resize(n);
  cloud.time_s.resize(n);
  for (int i = 0; i < n; ++i) {
    const double angle = 0.05 * i;
    cloud.points.col(i) << std::round(64.0 * 10.0 * std::cos(angle)) / 64.0,
        std::round(64.0 * 10.0 * std::sin(angle)) / 64.0, std::round(64.0 * 0.01 * i) / 64.0;
    cloud.intensity[i] = static_cast<float>(i % 256);
    cloud.time_s[i] = static_cast<float>(i) / 1024.0f;
  }
  return cloud;
}

// ---- a PLY composer, independent of the library's writer ----

struct TypeSpec {
  const char* name;  // as written in the header
  int size;
  bool is_float;
  bool is_signed;
};

const TypeSpec kPlyTypes[] = {
    {"char", 1, false, true},    {"uchar", 1, false, false},  {"short", 2, false, true},
    {"ushort", 2, false, false}, {"int", 4, false, true},     {"uint", 4, false, false},
    {"float", 4, true, true},    {"double", 8, true, true},   {"int8", 1, false, true},
    {"uint8", 1, false, false},  {"int16", 2, false, true},   {"uint16", 2, false, false},
    {"int32", 4, false, true},   {"uint32", 4, false, false}, {"float32", 4, true, true},
    {"float64", 8, true, true}};

void AppendValue(const TypeSpec& type, double value, bool big_endian, std::string* out) {
  unsigned char bytes[8] = {};
  if (type.is_float && type.size == 4) {
    const float v = static_cast<float>(value);
    std::memcpy(bytes, &v, 4);
  } else if (type.is_float) {
    std::memcpy(bytes, &value, 8);
  } else {
    const int64_t v = static_cast<int64_t>(value);
    // Two's complement little endian, truncated to the type size.
    for (int b = 0; b < type.size; ++b)
      bytes[b] = static_cast<unsigned char>((v >> (8 * b)) & 0xff);
    if (big_endian) {
      for (int b = 0; b < type.size / 2; ++b) std::swap(bytes[b], bytes[type.size - 1 - b]);
    }
    out->append(reinterpret_cast<const char*>(bytes), type.size);
    return;
  }
  // Floats were copied in host order; the test hosts are little endian (checked below).
  if (big_endian) {
    for (int b = 0; b < type.size / 2; ++b) std::swap(bytes[b], bytes[type.size - 1 - b]);
  }
  out->append(reinterpret_cast<const char*>(bytes), type.size);
}

bool HostIsLittleEndian() {
  const uint16_t one = 1;
  unsigned char first = 0;
  std::memcpy(&first, &one, 1);
  return first == 1;
}

// Vertex values representable in every type: integers in [-100, 100] (unsigned: [0, 200]).
std::vector<double> TypeSafeValues(const TypeSpec& type, int n, int axis) {
  std::vector<double> values(n);
  for (int i = 0; i < n; ++i) {
    const double v = static_cast<double>((i * (axis + 3) + 7 * axis) % 201);
    values[i] = type.is_signed ? v - 100.0 : v;
  }
  return values;
}

// format: "ascii", "binary_little_endian" or "binary_big_endian". The vertex element has
// an ignored uchar property before x, a list property after z (unless vertex_list is false:
// the reader's path for records of one size), then intensity; a face element follows.
std::string ComposePly(const std::string& format, const TypeSpec& type, int n,
                       bool vertex_list = true) {
  const bool ascii = format == "ascii";
  const bool big = format == "binary_big_endian";
  std::ostringstream header;
  header << "ply\nformat " << format << " 1.0\ncomment composed by the test\n"
         << "element vertex " << n << "\n"
         << "property uchar flags\n"
         << "property " << type.name << " x\nproperty " << type.name << " y\nproperty " << type.name
         << " z\n"
         << (vertex_list ? "property list uchar int extra\n" : "") << "property " << type.name
         << " intensity\n"
         << "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
  std::string out = header.str();
  const TypeSpec uchar = kPlyTypes[1];
  const TypeSpec int32 = kPlyTypes[4];
  std::vector<std::vector<double>> axes;
  for (int a = 0; a < 4; ++a) axes.push_back(TypeSafeValues(type, n, a));
  for (int i = 0; i < n; ++i) {
    const int list_length = i % 3;
    if (ascii) {
      std::ostringstream line;
      line.precision(17);
      line << (i % 7) << ' ' << axes[0][i] << ' ' << axes[1][i] << ' ' << axes[2][i];
      if (vertex_list) {
        line << ' ' << list_length;
        for (int k = 0; k < list_length; ++k) line << ' ' << k;
      }
      line << ' ' << axes[3][i] << '\n';
      out += line.str();
    } else {
      AppendValue(uchar, i % 7, big, &out);
      for (int a = 0; a < 3; ++a) AppendValue(type, axes[a][i], big, &out);
      if (vertex_list) {
        AppendValue(uchar, list_length, big, &out);
        for (int k = 0; k < list_length; ++k) AppendValue(int32, k, big, &out);
      }
      AppendValue(type, axes[3][i], big, &out);
    }
  }
  if (ascii) {
    out += "3 0 1 2\n";
  } else {
    AppendValue(uchar, 3, big, &out);
    for (int k = 0; k < 3; ++k) AppendValue(int32, k, big, &out);
  }
  return out;
}

TEST(PointCloudFileTest, RealPlyLoads) {
  const std::filesystem::path path = test::SharedDataDir("lidar_scan_pair") / "source.ply";
  AUTOCAL_REQUIRE_SHARED_DATA(path);
  const lidar::PointCloud cloud = ReadPointCloudFile(path.string());
  EXPECT_EQ(cloud.size(), 69792);
  EXPECT_TRUE(cloud.has_intensity());
  EXPECT_FALSE(cloud.has_time());
  EXPECT_TRUE(cloud.points.allFinite());
  // A real outdoor scan spans metres in x and y around the sensor.
  const Eigen::Vector3d extent =
      cloud.points.rowwise().maxCoeff() - cloud.points.rowwise().minCoeff();
  EXPECT_GT(extent.head<2>().minCoeff(), 5.0) << "extent " << extent.transpose();
}

TEST(PointCloudFileTest, WritePlyRoundTripsExactly) {
  const lidar::PointCloud cloud = HelixCloud(1000);
  const std::string path = OutPath("helix.ply");
  WritePly(path, cloud);
  const lidar::PointCloud read = ReadPointCloudFile(path);
  ASSERT_EQ(read.size(), cloud.size());
  ASSERT_TRUE(read.has_intensity());
  ASSERT_TRUE(read.has_time());
  for (int64_t i = 0; i < cloud.size(); ++i) {
    ASSERT_EQ(read.points.col(i), cloud.points.col(i)) << "point " << i;
    ASSERT_EQ(read.intensity[i], cloud.intensity[i]) << "point " << i;
    ASSERT_EQ(read.time_s[i], cloud.time_s[i]) << "point " << i;
  }
}

TEST(PointCloudFileTest, WritePlyRejectsNonFinitePoints) {
  lidar::PointCloud cloud = HelixCloud(10);
  cloud.points(1, 4) = std::nan("");
  EXPECT_THROW(WritePly(OutPath("nan.ply"), cloud), Error);
  // Finite as a double, infinite as the float the file stores: refused too.
  cloud = HelixCloud(10);
  cloud.points(0, 3) = 1e39;
  EXPECT_THROW(WritePly(OutPath("float_overflow.ply"), cloud), Error);
}

class PlyFormatTypeTest
    : public ::testing::TestWithParam<
          std::tuple<std::string, int /*index in kPlyTypes*/, bool /*vertex list*/>> {};

TEST_P(PlyFormatTypeTest, ReadsComposedFile) {
  ASSERT_TRUE(HostIsLittleEndian()) << "the PLY composer assumes a little-endian host";
  const std::string format = std::get<0>(GetParam());
  const TypeSpec& type = kPlyTypes[std::get<1>(GetParam())];
  const bool vertex_list = std::get<2>(GetParam());
  const int n = 57;
  const std::string path =
      OutPath(format + "_" + type.name + (vertex_list ? "_list" : "") + ".ply");
  WriteBytes(path, ComposePly(format, type, n, vertex_list));
  const lidar::PointCloud cloud = ReadPointCloudFile(path);
  ASSERT_EQ(cloud.size(), n);
  ASSERT_TRUE(cloud.has_intensity());
  EXPECT_FALSE(cloud.has_time());
  for (int a = 0; a < 3; ++a) {
    const std::vector<double> expected = TypeSafeValues(type, n, a);
    for (int i = 0; i < n; ++i) {
      ASSERT_EQ(cloud.points(a, i), expected[i])
          << format << " " << type.name << " axis " << a << " point " << i;
    }
  }
  const std::vector<double> intensity = TypeSafeValues(type, n, 3);
  for (int i = 0; i < n; ++i) ASSERT_EQ(cloud.intensity[i], intensity[i]) << "point " << i;
}

INSTANTIATE_TEST_SUITE_P(
    AllFormatsAndTypes, PlyFormatTypeTest,
    ::testing::Combine(::testing::Values("ascii", "binary_little_endian", "binary_big_endian"),
                       ::testing::Range(0, static_cast<int>(std::size(kPlyTypes))),
                       ::testing::Bool()),
    [](const ::testing::TestParamInfo<PlyFormatTypeTest::ParamType>& info) {
      return std::get<0>(info.param) + "_" + kPlyTypes[std::get<1>(info.param)].name +
             (std::get<2>(info.param) ? "_list" : "");
    });

TEST(PointCloudFileTest, PlyTimeAndScalarIntensityAliases) {
  const std::string path = OutPath("aliases.ply");
  WriteBytes(path,
             "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
             "property float z\nproperty float scalar_intensity\nproperty double time\n"
             "end_header\n1 2 3 4 0.25\n-1 -2 -3 5 0.5\n");
  const lidar::PointCloud cloud = ReadPointCloudFile(path);
  ASSERT_EQ(cloud.size(), 2);
  ASSERT_TRUE(cloud.has_time());
  EXPECT_EQ(cloud.points.col(1), Eigen::Vector3d(-1, -2, -3));
  EXPECT_EQ(cloud.intensity[1], 5.0f);
  EXPECT_EQ(cloud.time_s[1], 0.5);
}

// A point's time takes its unit from its type, as the bag importer reads it: an integer `t`
// (Ouster's uint32 offsets) is nanoseconds, a floating point one seconds. Read as seconds, an
// Ouster `t` became up to 1e8 s, which nothing downstream refused.
TEST(PointCloudFileTest, IntegerPointTimesAreNanoseconds) {
  const std::string ply_path = OutPath("ouster_t.ply");
  WriteBytes(ply_path,
             "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
             "property float z\nproperty uint t\nend_header\n1 2 3 0\n-1 -2 -3 99000000\n");
  const std::string pcd_path = OutPath("ouster_t.pcd");
  WriteBytes(pcd_path,
             "VERSION 0.7\nFIELDS x y z t\nSIZE 4 4 4 4\nTYPE F F F U\nCOUNT 1 1 1 1\nWIDTH 2\n"
             "HEIGHT 1\nPOINTS 2\nDATA ascii\n1 2 3 0\n-1 -2 -3 99000000\n");
  for (const std::string& path : {ply_path, pcd_path}) {
    const lidar::PointCloud cloud = ReadPointCloudFile(path);
    ASSERT_TRUE(cloud.has_time()) << path;
    EXPECT_EQ(cloud.time_s[0], 0.0) << path;
    EXPECT_NEAR(cloud.time_s[1], 0.099, 1e-15) << path;
  }
}

// ---- PCD ----

std::string PcdHeader(const std::string& data, int n) {
  return "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n"
         "FIELDS x y z normal intensity t\nSIZE 4 4 8 4 2 8\nTYPE F F F F U F\n"
         "COUNT 1 1 1 3 1 1\nWIDTH " +
         std::to_string(n) + "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " + std::to_string(n) +
         "\nDATA " + data + "\n";
}

// A PCD file of `cloud` with an ignored 3-float normal between z and intensity, mixed
// sizes (z and t are doubles, intensity a uint16).
std::string ComposePcd(const std::string& data, const lidar::PointCloud& cloud) {
  const int n = static_cast<int>(cloud.size());
  std::string out = PcdHeader(data, n);
  for (int i = 0; i < n; ++i) {
    if (data == "ascii") {
      std::ostringstream line;
      line.precision(17);
      line << cloud.points(0, i) << ' ' << cloud.points(1, i) << ' ' << cloud.points(2, i)
           << " 0 0 1 " << cloud.intensity[i] << ' ' << cloud.time_s[i] << '\n';
      out += line.str();
      continue;
    }
    const float x = static_cast<float>(cloud.points(0, i));
    const float y = static_cast<float>(cloud.points(1, i));
    const double z = cloud.points(2, i);
    const float normal[3] = {0.0f, 0.0f, 1.0f};
    const uint16_t intensity = static_cast<uint16_t>(cloud.intensity[i]);
    const double t = cloud.time_s[i];
    out.append(reinterpret_cast<const char*>(&x), 4);
    out.append(reinterpret_cast<const char*>(&y), 4);
    out.append(reinterpret_cast<const char*>(&z), 8);
    out.append(reinterpret_cast<const char*>(normal), 12);
    out.append(reinterpret_cast<const char*>(&intensity), 2);
    out.append(reinterpret_cast<const char*>(&t), 8);
  }
  return out;
}

TEST(PointCloudFileTest, PcdAsciiAndBinaryRoundTrip) {
  ASSERT_TRUE(HostIsLittleEndian());
  const lidar::PointCloud cloud = HelixCloud(200);
  const std::string ascii = ComposePcd("ascii", cloud);
  const std::string binary = ComposePcd("binary", cloud);
  for (const auto& [name, bytes] :
       {std::pair<std::string, std::string>{"ascii.pcd", ascii}, {"binary.PCD", binary}}) {
    const std::string path = OutPath(name);
    WriteBytes(path, bytes);
    const lidar::PointCloud read = ReadPointCloudFile(path);
    ASSERT_EQ(read.size(), cloud.size()) << name;
    ASSERT_TRUE(read.has_intensity() && read.has_time()) << name;
    for (int64_t i = 0; i < cloud.size(); ++i) {
      ASSERT_EQ(read.points.col(i), cloud.points.col(i)) << name << " point " << i;
      ASSERT_EQ(read.intensity[i], cloud.intensity[i]) << name << " point " << i;
      ASSERT_EQ(read.time_s[i], cloud.time_s[i]) << name << " point " << i;
    }
  }
}

// ---- bad input ----

// Runs `read` on `path`, expects a ParseError and returns it.
ParseError ExpectParseError(const std::string& path) {
  try {
    ReadPointCloudFile(path);
  } catch (const ParseError& e) {
    EXPECT_EQ(e.location().file, path);
    return e;
  }
  ADD_FAILURE() << "no ParseError for " << path;
  return ParseError(SourceLocation{}, "none");
}

// A time beyond one second from the sweep's stamp is not a time within a sweep: a float `t`
// written in nanoseconds, or an integer one in microseconds, is refused where it stands.
TEST(PointCloudFileTest, PointTimesBeyondASecondAreRefused) {
  const std::string ply_path = OutPath("t_in_ns.ply");
  WriteBytes(ply_path,
             "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
             "property float z\nproperty double time\nend_header\n1 2 3 0.05\n-1 -2 -3 "
             "50000000\n");
  const ParseError ply = ExpectParseError(ply_path);
  EXPECT_EQ(ply.location().line, 10);
  EXPECT_THAT(ply.detail(),
              HasSubstr("vertex 1 has time 5e+07 (a floating point property: "
                        "seconds), not a time within one sweep (expected |t| <= 1 s"));
  const std::string pcd_path = OutPath("t_in_us.pcd");
  WriteBytes(pcd_path,
             "VERSION 0.7\nFIELDS x y z t\nSIZE 4 4 4 4\nTYPE F F F U\nCOUNT 1 1 1 1\nWIDTH 1\n"
             "HEIGHT 1\nPOINTS 1\nDATA binary\n" +
                 std::string(12, '\0') + std::string("\x00\xca\x9a\x3c", 4));
  const ParseError pcd = ExpectParseError(pcd_path);
  EXPECT_THAT(pcd.detail(), HasSubstr("point 0 has time 1016777216 (an integer property: "
                                      "nanoseconds), not a time within one sweep"));
}

TEST(PointCloudFileTest, EmptyPlyFile) {
  const std::string path = OutPath("empty.ply");
  WriteBytes(path, "");
  const ParseError e = ExpectParseError(path);
  EXPECT_EQ(e.location().byte_offset, 0);
  EXPECT_THAT(e.detail(), HasSubstr("empty file"));
}

TEST(PointCloudFileTest, NotAPlyFile) {
  const std::string path = OutPath("magic.ply");
  WriteBytes(path, "PCD\nformat ascii 1.0\n");
  const ParseError e = ExpectParseError(path);
  EXPECT_EQ(e.location().line, 1);
  EXPECT_EQ(e.location().column, 1);
  EXPECT_THAT(e.detail(), HasSubstr("'ply'"));
}

TEST(PointCloudFileTest, TruncatedPlyHeader) {
  const std::string full = ComposePly("binary_little_endian", kPlyTypes[6], 10);
  const std::string path = OutPath("truncated_header.ply");
  const size_t cut = full.find("end_header") - 5;
  WriteBytes(path, full.substr(0, cut));
  const ParseError e = ExpectParseError(path);
  EXPECT_EQ(e.location().byte_offset, static_cast<int64_t>(cut));
  EXPECT_THAT(e.detail(), HasSubstr("end_header"));
}

TEST(PointCloudFileTest, TruncatedBinaryPlyBody) {
  const lidar::PointCloud cloud = HelixCloud(100);
  const std::string good = OutPath("good.ply");
  WritePly(good, cloud);
  std::ifstream in(good, std::ios::binary);
  const std::string full((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  for (const size_t drop : {size_t{1}, size_t{20 * 50}}) {
    const std::string path = OutPath("truncated_body.ply");
    const std::string cut = full.substr(0, full.size() - drop);
    WriteBytes(path, cut);
    const ParseError e = ExpectParseError(path);
    EXPECT_EQ(e.location().byte_offset, static_cast<int64_t>(cut.size())) << "drop " << drop;
    EXPECT_THAT(e.detail(), HasSubstr("truncated")) << "drop " << drop;
  }
}

TEST(PointCloudFileTest, TruncatedAsciiPlyBody) {
  const std::string full = ComposePly("ascii", kPlyTypes[6], 10);
  const std::string path = OutPath("truncated_ascii.ply");
  // Drop the face line and the last two vertex lines.
  std::string cut = full;
  for (int k = 0; k < 3; ++k) cut.erase(cut.rfind('\n', cut.size() - 2) + 1);
  WriteBytes(path, cut);
  const ParseError e = ExpectParseError(path);
  EXPECT_EQ(e.location().byte_offset, static_cast<int64_t>(cut.size()));
  EXPECT_THAT(e.detail(), HasSubstr("vertex 8 of 10"));
}

// Every prefix of a binary file is a ParseError naming the byte where the data ran out,
// unless the cut falls after the vertex data (in the ignored face element). An ascii
// prefix cut inside the last number still reads as numbers, so there only "no crash, a
// ParseError or all six points" holds. Parsed from memory to keep the test fast.
TEST(PointCloudFileTest, EveryTruncationIsAParseError) {
  for (const bool vertex_list : {true, false}) {
    for (const std::string format : {"binary_little_endian", "binary_big_endian", "ascii"}) {
      const bool ascii = format == "ascii";
      const std::string full = ComposePly(format, kPlyTypes[7], 6, vertex_list);
      const size_t header_end = full.find("end_header\n") + 11;
      const size_t face_start = ascii ? full.rfind("3 0 1 2") : full.size() - 13;
      for (size_t length = 0; length < full.size(); ++length) {
        try {
          const lidar::PointCloud cloud =
              internal::ParsePly("prefix.ply", full.substr(0, length), {});
          if (!ascii) {
            EXPECT_GE(length, face_start) << format << " length " << length;
          }
          EXPECT_EQ(cloud.size(), 6) << format << " length " << length;
        } catch (const ParseError& e) {
          EXPECT_LT(length, face_start) << format << " length " << length << ": " << e.what();
          if (!ascii && length >= header_end) {
            EXPECT_EQ(e.location().byte_offset, static_cast<int64_t>(length)) << e.what();
          }
        }
      }
    }
  }
}

TEST(PointCloudFileTest, EveryPcdTruncationIsAParseError) {
  const lidar::PointCloud cloud = HelixCloud(5);
  for (const std::string data : {"binary", "ascii"}) {
    const std::string full = ComposePcd(data, cloud);
    const size_t header_end = full.find("DATA") + data.size() + 6;
    for (size_t length = 0; length < full.size(); ++length) {
      try {
        const lidar::PointCloud read = internal::ParsePcd("prefix.pcd", full.substr(0, length), {});
        // Only an ascii cut inside the last number can still parse.
        EXPECT_EQ(data, "ascii") << "length " << length;
        EXPECT_GT(length, full.rfind(' ') + 1) << data << " length " << length;
      } catch (const ParseError& e) {
        if (data == "binary" && length >= header_end) {
          EXPECT_EQ(e.location().byte_offset, static_cast<int64_t>(length)) << e.what();
        }
      }
    }
  }
}

TEST(PointCloudFileTest, PlyWithoutZ) {
  const std::string path = OutPath("no_z.ply");
  WriteBytes(path,
             "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
             "property float intensity\nend_header\n1 2 3\n");
  const ParseError e = ExpectParseError(path);
  EXPECT_EQ(e.location().line, 3);  // the `element vertex` line
  EXPECT_THAT(e.detail(), HasSubstr("no property 'z'"));
}

TEST(PointCloudFileTest, PlyUnknownPropertyType) {
  const std::string path = OutPath("bad_type.ply");
  WriteBytes(path,
             "ply\nformat ascii 1.0\nelement vertex 1\nproperty float32 x\nproperty half y\n");
  const ParseError e = ExpectParseError(path);
  EXPECT_EQ(e.location().line, 5);
  EXPECT_EQ(e.location().column, 10);
  EXPECT_THAT(e.detail(), HasSubstr("'half'"));
}

TEST(PointCloudFileTest, AsciiPlyWithTooManyAndTooFewValues) {
  const std::string head =
      "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
      "property float z\nend_header\n1 2 3\n";
  const std::string many = OutPath("many.ply");
  WriteBytes(many, head + "4 5 6 7\n");
  ParseError e = ExpectParseError(many);
  EXPECT_EQ(e.location().line, 9);
  EXPECT_EQ(e.location().column, 7);
  EXPECT_THAT(e.detail(), HasSubstr("more values"));
  const std::string few = OutPath("few.ply");
  WriteBytes(few, head + "4 5\n6 7 8\n");
  e = ExpectParseError(few);
  EXPECT_EQ(e.location().line, 9);
  EXPECT_EQ(e.location().column, 4);
  EXPECT_THAT(e.detail(), HasSubstr("fewer values"));
}

TEST(PointCloudFileTest, AsciiPlyTextInNumber) {
  const std::string path = OutPath("text.ply");
  WriteBytes(path,
             "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
             "property float z\nend_header\n1 2.5x 3\n");
  const ParseError e = ExpectParseError(path);
  EXPECT_EQ(e.location().line, 8);
  EXPECT_EQ(e.location().column, 3);
  EXPECT_THAT(e.detail(), HasSubstr("trailing characters 'x'"));
}

TEST(PointCloudFileTest, NonFinitePointRejectedOrDropped) {
  lidar::PointCloud cloud = HelixCloud(5);
  const std::string path = OutPath("nan.pcd");
  std::string text =
      "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 5\nHEIGHT 1\nPOINTS 5\nDATA ascii\n";
  for (int i = 0; i < 5; ++i) {
    text +=
        (i == 2 ? std::string("nan nan nan") : std::to_string(cloud.points(0, i)) + " 0 0") + "\n";
  }
  WriteBytes(path, text);
  const ParseError e = ExpectParseError(path);
  EXPECT_EQ(e.location().line, 10);
  EXPECT_THAT(e.detail(), HasSubstr("non-finite x"));
  PointCloudReadOptions options;
  options.drop_non_finite_points = true;
  EXPECT_EQ(ReadPointCloudFile(path, options).size(), 4);
}

TEST(PointCloudFileTest, PcdBinaryCompressedIsUnsupported) {
  const std::string path = OutPath("compressed.pcd");
  WriteBytes(path,
             "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 1\n"
             "HEIGHT 1\nPOINTS 1\nDATA binary_compressed\n");
  const ParseError e = ExpectParseError(path);
  EXPECT_EQ(e.location().line, 9);
  EXPECT_EQ(e.location().column, 6);
  EXPECT_THAT(e.detail(), HasSubstr("unsupported"));
}

TEST(PointCloudFileTest, TruncatedBinaryPcd) {
  const std::string header = PcdHeader("binary", 10);
  const std::string path = OutPath("truncated.pcd");
  WriteBytes(path, header + std::string(38 * 10 - 3, '\0'));
  const ParseError e = ExpectParseError(path);
  EXPECT_EQ(e.location().byte_offset, static_cast<int64_t>(header.size() + 38 * 10 - 3));
  EXPECT_THAT(e.detail(), HasSubstr("truncated"));
}

// Points beyond the header's POINTS (a writer that never updated the count) are refused, as the
// PLY reader refuses data after its elements, instead of being dropped silently; trailing blank
// lines are fine.
TEST(PointCloudFileTest, PcdDataBeyondItsPointsIsRefused) {
  const lidar::PointCloud cloud = HelixCloud(4);
  const std::string ascii = ComposePcd("ascii", cloud);
  const std::string binary = ComposePcd("binary", cloud);
  const auto declaring_two = [](std::string file) {
    for (const auto& [from, to] : {std::pair<std::string, std::string>{"WIDTH 4\n", "WIDTH 2\n"},
                                   {"POINTS 4\n", "POINTS 2\n"}}) {
      file.replace(file.find(from), from.size(), to);
    }
    return file;
  };
  const std::string blank_lines = OutPath("blank_lines.pcd");
  WriteBytes(blank_lines, ascii + "\n  \n");
  EXPECT_EQ(ReadPointCloudFile(blank_lines).size(), 4);
  const std::string ascii_path = OutPath("ascii_beyond.pcd");
  WriteBytes(ascii_path, declaring_two(ascii));
  const ParseError a = ExpectParseError(ascii_path);
  EXPECT_EQ(a.location().line, 14);  // the third point's line, after an 11-line header
  EXPECT_THAT(a.detail(), HasSubstr("data after the 2 points the header declares (POINTS 2)"));
  const std::string binary_path = OutPath("binary_beyond.pcd");
  const std::string binary_two = declaring_two(binary);
  WriteBytes(binary_path, binary_two);
  const ParseError b = ExpectParseError(binary_path);
  EXPECT_EQ(b.location().byte_offset, static_cast<int64_t>(binary_two.size() - 2 * 38));
  EXPECT_THAT(b.detail(), HasSubstr("76 bytes of data after the 2 points"));
}

TEST(PointCloudFileTest, PcdWithoutY) {
  const std::string path = OutPath("no_y.pcd");
  WriteBytes(path, "FIELDS x z\nSIZE 4 4\nTYPE F F\nWIDTH 1\nPOINTS 1\nDATA ascii\n1 2\n");
  const ParseError e = ExpectParseError(path);
  EXPECT_EQ(e.location().line, 6);
  EXPECT_THAT(e.detail(), HasSubstr("no 'y'"));
}

TEST(PointCloudFileTest, UnknownExtensionMissingFileAndDirectory) {
  EXPECT_THROW(ReadPointCloudFile(OutPath("cloud.xyz")), Error);
  std::filesystem::create_directories(OutPath("directory.ply"));
  try {
    ReadPointCloudFile(OutPath("directory.ply"));
    FAIL() << "no error for a directory";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), HasSubstr("is a directory"));
  }
  try {
    ReadPointCloudFile(OutPath("does_not_exist.ply"));
    FAIL() << "no error for a missing file";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), HasSubstr("does_not_exist.ply"));
  }
}

}  // namespace
}  // namespace io
}  // namespace autocal
