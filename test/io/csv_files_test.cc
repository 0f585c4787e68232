#include "autocal/io/csv_files.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <iterator>
#include <random>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/units.h"
#include "io/io_test_data.h"
#include "support/test_paths.h"

namespace autocal {
namespace io {
namespace {

using ::testing::HasSubstr;

std::string OutPath(const std::string& name) {
  return (test::OutputDir("csv_files") / name).string();
}

std::string ReadText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

void WriteText(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << text;
}

std::vector<std::string> Lines(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

std::string JoinLines(const std::vector<std::string>& lines) {
  std::string text;
  for (const std::string& line : lines) text += line + "\n";
  return text;
}

// 1-based column where comma-separated field `field` (0-based) of `line` starts.
int64_t FieldColumn(const std::string& line, int field) {
  size_t pos = 0;
  for (int i = 0; i < field; ++i) pos = line.find(',', pos) + 1;
  return static_cast<int64_t>(pos) + 1;
}

// Replaces field `field` of line `line` (1-based, as an editor shows it).
std::string ReplaceField(std::vector<std::string> lines, int line, int field,
                         const std::string& value) {
  std::string& text = lines[line - 1];
  const size_t start = FieldColumn(text, field) - 1;
  const size_t end = std::min(text.find(',', start), text.size());
  text.replace(start, end - start, value);
  return JoinLines(lines);
}

struct Expected {
  int64_t line;
  int64_t column;
  std::string message;
};

template <typename Read>
void ExpectParseError(const std::string& path, Read read, const Expected& expected) {
  try {
    read(path);
    ADD_FAILURE() << "no ParseError for " << path;
  } catch (const ParseError& e) {
    EXPECT_EQ(e.location().file, path);
    EXPECT_EQ(e.location().line, expected.line) << e.what();
    EXPECT_EQ(e.location().column, expected.column) << e.what();
    EXPECT_THAT(e.detail(), HasSubstr(expected.message)) << e.what();
  }
}

const auto kReadImu = [](const std::string& path) { ReadImuCsv(path); };

// imu.csv of the reference drive as lines, header first.
std::vector<std::string> ImuLines() {
  const std::string path = OutPath("reference_imu.csv");
  WriteImuCsv(path, test_data::MakeDrive(2.0).imu);
  return Lines(ReadText(path));
}

// ---- round trips ----

TEST(CsvFilesTest, ImuRoundTripsExactly) {
  const sensors::ImuSamples imu = test_data::MakeDrive(3.0).imu;
  const std::string path = OutPath("imu.csv");
  WriteImuCsv(path, imu);
  const sensors::ImuSamples read = ReadImuCsv(path);
  ASSERT_EQ(read.size(), imu.size());
  for (size_t i = 0; i < imu.size(); ++i) {
    ASSERT_EQ(read[i].t_ns, imu[i].t_ns) << "sample " << i;
    ASSERT_EQ(read[i].gyro_rad_s, imu[i].gyro_rad_s) << "sample " << i;
    ASSERT_EQ(read[i].accel_m_s2, imu[i].accel_m_s2)
        << "sample " << i << "\nread " << read[i].accel_m_s2.transpose() << "\nwrote "
        << imu[i].accel_m_s2.transpose();
  }
}

TEST(CsvFilesTest, WheelGnssLidarRoundTripExactly) {
  const test_data::Drive drive = test_data::MakeDrive(3.0);
  WriteWheelCsv(OutPath("wheel.csv"), drive.wheel);
  const sensors::WheelSamples wheel = ReadWheelCsv(OutPath("wheel.csv"));
  ASSERT_EQ(wheel.size(), drive.wheel.size());
  for (size_t i = 0; i < wheel.size(); ++i) {
    ASSERT_EQ(wheel[i].t_ns, drive.wheel[i].t_ns) << "sample " << i;
    ASSERT_EQ(wheel[i].left_rad_s, drive.wheel[i].left_rad_s) << "sample " << i;
    ASSERT_EQ(wheel[i].right_rad_s, drive.wheel[i].right_rad_s) << "sample " << i;
  }
  WriteGnssCsv(OutPath("gnss.csv"), drive.gnss);
  const sensors::GnssFixes gnss = ReadGnssCsv(OutPath("gnss.csv"));
  ASSERT_EQ(gnss.size(), drive.gnss.size());
  for (size_t i = 0; i < gnss.size(); ++i) {
    ASSERT_EQ(gnss[i].t_ns, drive.gnss[i].t_ns) << "fix " << i;
    ASSERT_EQ(gnss[i].lat_deg, drive.gnss[i].lat_deg) << "fix " << i;
    ASSERT_EQ(gnss[i].lon_deg, drive.gnss[i].lon_deg) << "fix " << i;
    ASSERT_EQ(gnss[i].alt_m, drive.gnss[i].alt_m) << "fix " << i;
    ASSERT_EQ(gnss[i].std_enu_m, drive.gnss[i].std_enu_m) << "fix " << i;
  }
  std::vector<LidarSweepRef> sweeps;
  for (const lidar::LidarSweep& sweep : drive.sweeps)
    sweeps.push_back({sweep.t_ns, std::to_string(sweep.t_ns) + ".ply"});
  WriteLidarCsv(OutPath("lidar.csv"), sweeps);
  const std::vector<LidarSweepRef> read = ReadLidarCsv(OutPath("lidar.csv"));
  ASSERT_EQ(read.size(), sweeps.size());
  for (size_t i = 0; i < read.size(); ++i) {
    ASSERT_EQ(read[i].t_ns, sweeps[i].t_ns) << "row " << i;
    ASSERT_EQ(read[i].file, sweeps[i].file) << "row " << i;
  }
}

TEST(CsvFilesTest, TrajectoryRoundTripsExactly) {
  const Trajectory trajectory = test_data::MakeDrive(3.0).trajectory;
  WriteTrajectoryCsv(OutPath("trajectory.csv"), trajectory);
  const Trajectory read = ReadTrajectoryCsv(OutPath("trajectory.csv"));
  ASSERT_EQ(read.size(), trajectory.size());
  for (size_t i = 0; i < read.size(); ++i) {
    ASSERT_EQ(read[i].t_ns, trajectory[i].t_ns) << "pose " << i;
    ASSERT_EQ(read[i].T_W_I.p, trajectory[i].T_W_I.p) << "pose " << i;
    ASSERT_EQ(read[i].T_W_I.q.coeffs(), trajectory[i].T_W_I.q.coeffs())
        << "pose " << i << "\nread " << read[i].T_W_I.q.coeffs().transpose() << "\nwrote "
        << trajectory[i].T_W_I.q.coeffs().transpose();
    ASSERT_EQ(read[i].v_W_I, trajectory[i].v_W_I) << "pose " << i;
  }
}

TEST(CsvFilesTest, AcceptsBomEuRoCStyleHeaderBlanksAndCrLf) {
  std::vector<std::string> lines = ImuLines();
  // A byte order mark, as spreadsheet exports write it, then an EuRoC-style header.
  lines[0] = "\xEF\xBB\xBF#t_ns, gx, gy, gz, ax, ay, az\r";
  for (size_t i = 1; i < lines.size(); ++i) lines[i] += "\r";
  WriteText(OutPath("crlf.csv"), JoinLines(lines));
  EXPECT_EQ(ReadImuCsv(OutPath("crlf.csv")).size(), lines.size() - 1);
}

// ---- bad input ----

TEST(CsvFilesTest, EmptyFile) {
  WriteText(OutPath("empty.csv"), "");
  ExpectParseError(OutPath("empty.csv"), kReadImu, {1, 1, "empty file"});
}

TEST(CsvFilesTest, HeaderOnlyImuHasNoSamples) {
  WriteText(OutPath("header_only.csv"), ImuLines()[0] + "\n");
  ExpectParseError(OutPath("header_only.csv"), kReadImu, {2, 1, "no IMU samples"});
}

TEST(CsvFilesTest, MissingHeader) {
  std::vector<std::string> lines = ImuLines();
  lines.erase(lines.begin());
  WriteText(OutPath("no_header.csv"), JoinLines(lines));
  ExpectParseError(OutPath("no_header.csv"), kReadImu, {1, 1, "missing header line"});
}

TEST(CsvFilesTest, WrongHeaderName) {
  const std::vector<std::string> lines = ImuLines();
  WriteText(OutPath("bad_header.csv"), ReplaceField(lines, 1, 6, "acc_z"));
  ExpectParseError(OutPath("bad_header.csv"), kReadImu,
                   {1, FieldColumn(lines[0], 6), "is 'acc_z', expected 'az'"});
}

// A '#' with no name after it (an EuRoC-style header cut short) is named at the column after
// the '#' (the column was a pointer difference against an empty name).
TEST(CsvFilesTest, EmptyHashedHeaderName) {
  std::vector<std::string> lines = ImuLines();
  lines[0] = "# ,gx,gy,gz,ax,ay,az";
  WriteText(OutPath("hash_header.csv"), JoinLines(lines));
  ExpectParseError(OutPath("hash_header.csv"), kReadImu,
                   {1, 2, "header column 1 is '', expected 't_ns'"});
}

TEST(CsvFilesTest, HeaderWithTooFewColumns) {
  WriteText(OutPath("short_header.csv"), "t_ns,gx,gy,gz,ax,ay\n");
  ExpectParseError(OutPath("short_header.csv"), kReadImu,
                   {1, 20, "header has 6 columns, expected 7"});
}

TEST(CsvFilesTest, RowWithTooFewColumns) {
  std::vector<std::string> lines = ImuLines();
  lines[4] = lines[4].substr(0, lines[4].rfind(','));
  WriteText(OutPath("few.csv"), JoinLines(lines));
  ExpectParseError(OutPath("few.csv"), kReadImu,
                   {5, static_cast<int64_t>(lines[4].size()) + 1, "expected 7 columns"});
}

TEST(CsvFilesTest, RowWithTooManyColumns) {
  std::vector<std::string> lines = ImuLines();
  lines[6] += ",0.5";
  WriteText(OutPath("many.csv"), JoinLines(lines));
  ExpectParseError(OutPath("many.csv"), kReadImu, {7, FieldColumn(lines[6], 7), "found 8"});
}

TEST(CsvFilesTest, TextInNumber) {
  const std::vector<std::string> lines = ImuLines();
  WriteText(OutPath("text.csv"), ReplaceField(lines, 9, 2, "abc"));
  ExpectParseError(OutPath("text.csv"), kReadImu,
                   {9, FieldColumn(lines[8], 2), "gy: expected a number, found 'abc'"});
}

TEST(CsvFilesTest, TrailingGarbageInNumber) {
  const std::vector<std::string> lines = ImuLines();
  WriteText(OutPath("garbage.csv"), ReplaceField(lines, 3, 5, "0.25m"));
  ExpectParseError(OutPath("garbage.csv"), kReadImu,
                   {3, FieldColumn(lines[2], 5), "trailing characters 'm'"});
}

TEST(CsvFilesTest, TrailingGarbageInTimestamp) {
  const std::vector<std::string> lines = ImuLines();
  WriteText(OutPath("garbage_t.csv"),
            ReplaceField(lines, 3, 0, lines[2].substr(0, lines[2].find(',')) + ".5"));
  ExpectParseError(OutPath("garbage_t.csv"), kReadImu, {3, 1, "trailing characters '.5'"});
}

TEST(CsvFilesTest, NaNAndInf) {
  const std::vector<std::string> lines = ImuLines();
  WriteText(OutPath("nan.csv"), ReplaceField(lines, 11, 4, "nan"));
  ExpectParseError(OutPath("nan.csv"), kReadImu,
                   {11, FieldColumn(lines[10], 4), "ax: non-finite value 'nan'"});
  WriteText(OutPath("inf.csv"), ReplaceField(lines, 12, 3, "-inf"));
  ExpectParseError(OutPath("inf.csv"), kReadImu,
                   {12, FieldColumn(lines[11], 3), "gz: non-finite value '-inf'"});
  WriteText(OutPath("overflow.csv"), ReplaceField(lines, 13, 1, "1e999"));
  ExpectParseError(OutPath("overflow.csv"), kReadImu,
                   {13, FieldColumn(lines[12], 1), "out of the range"});
}

TEST(CsvFilesTest, NonMonotonicAndDuplicateTime) {
  std::vector<std::string> lines = ImuLines();
  std::swap(lines[20], lines[21]);
  WriteText(OutPath("non_monotonic.csv"), JoinLines(lines));
  ExpectParseError(OutPath("non_monotonic.csv"), kReadImu, {22, 1, "non-monotonic timestamp"});
  lines = ImuLines();
  lines[30] = lines[31];
  WriteText(OutPath("duplicate.csv"), JoinLines(lines));
  ExpectParseError(OutPath("duplicate.csv"), kReadImu, {32, 1, "duplicate timestamp"});
}

TEST(CsvFilesTest, EmptyLineInData) {
  std::vector<std::string> lines = ImuLines();
  lines[10] = "";
  WriteText(OutPath("blank.csv"), JoinLines(lines));
  ExpectParseError(OutPath("blank.csv"), kReadImu, {11, 1, "empty line"});
}

TEST(CsvFilesTest, GyroInDegreesPerSecond) {
  sensors::ImuSamples imu = test_data::MakeDrive(2.0).imu;
  for (sensors::ImuSample& s : imu) s.gyro_rad_s *= kRadToDeg;
  WriteImuCsv(OutPath("deg_s.csv"), imu);
  const std::vector<std::string> lines = Lines(ReadText(OutPath("deg_s.csv")));
  // The reference drive turns at 0.25 rad/s = 14.3 "rad/s" in deg/s, from the first row.
  ExpectParseError(OutPath("deg_s.csv"), kReadImu,
                   {2, FieldColumn(lines[1], 1), "seems to be in deg/s"});
}

TEST(CsvFilesTest, GyroCheckToleratesRareSpikes) {
  sensors::ImuSamples imu = test_data::MakeDrive(2.0).imu;
  // 0.5% of the samples at 10 rad/s (a pothole, a glitch): below the 99th percentile.
  for (size_t i = 0; i < imu.size(); i += 200) imu[i].gyro_rad_s.x() = 10.0;
  WriteImuCsv(OutPath("spikes.csv"), imu);
  EXPECT_EQ(ReadImuCsv(OutPath("spikes.csv")).size(), imu.size());
}

TEST(CsvFilesTest, AccelerometerWithoutGravity) {
  sensors::ImuSamples imu = test_data::MakeDrive(2.0).imu;
  // The IMU only yaws, so gravity is exactly +g on its z axis.
  for (sensors::ImuSample& s : imu) s.accel_m_s2.z() -= test_data::kGravity;
  WriteImuCsv(OutPath("no_gravity.csv"), imu);
  const std::vector<std::string> lines = Lines(ReadText(OutPath("no_gravity.csv")));
  ExpectParseError(OutPath("no_gravity.csv"), kReadImu,
                   {2, FieldColumn(lines[1], 4), "accelerometer seems to exclude gravity"});
}

TEST(CsvFilesTest, AccelerometerInG) {
  sensors::ImuSamples imu = test_data::MakeDrive(2.0).imu;
  for (sensors::ImuSample& s : imu) s.accel_m_s2 /= test_data::kGravity;
  WriteImuCsv(OutPath("in_g.csv"), imu);
  const std::vector<std::string> lines = Lines(ReadText(OutPath("in_g.csv")));
  ExpectParseError(OutPath("in_g.csv"), kReadImu, {2, FieldColumn(lines[1], 4), "units of g"});
}

TEST(CsvFilesTest, AccelerometerInFeetPerSecondSquared) {
  sensors::ImuSamples imu = test_data::MakeDrive(2.0).imu;
  for (sensors::ImuSample& s : imu) s.accel_m_s2 /= 0.3048;
  WriteImuCsv(OutPath("in_ft.csv"), imu);
  const std::vector<std::string> lines = Lines(ReadText(OutPath("in_ft.csv")));
  ExpectParseError(OutPath("in_ft.csv"), kReadImu,
                   {2, FieldColumn(lines[1], 4), "far above gravity"});
}

// One corrupt row (a digit lost its decimal point) is refused at its own line as beyond any
// IMU's range; the unit checks take the median and do not mistake it for a unit.
TEST(CsvFilesTest, ACorruptRowIsRefusedAtItsLine) {
  const sensors::ImuSamples imu = test_data::MakeDrive(2.0).imu;
  WriteImuCsv(OutPath("corrupt_ref.csv"), imu);
  const std::vector<std::string> lines = Lines(ReadText(OutPath("corrupt_ref.csv")));
  const int line = 300;
  // (field replaced, its value, the field the message points at: ax or gx, the message)
  for (const auto& [field, value, at, message] :
       {std::tuple{6, "200000", 4, "|a| = 2e+05 m/s^2 = 2.04e+04 g, beyond any accelerometer's"},
        std::tuple{6, "1e308", 4, "beyond any accelerometer's range (200 g)"},
        std::tuple{2, "-90", 1, "|omega| = 90 rad/s, beyond any gyroscope's range (69.8 rad/s)"}}) {
    WriteText(OutPath("corrupt.csv"), ReplaceField(lines, line, field, value));
    ExpectParseError(OutPath("corrupt.csv"), kReadImu,
                     {line, FieldColumn(lines[line - 1], at), message});
  }
}

TEST(CsvFilesTest, ImuBiasRoundTripsExactlyAndNamesABadField) {
  ImuBiasTrajectory biases;
  for (int k = 0; k < 5; ++k) {
    biases.push_back({int64_t{1'700'000'000'000'000'000} + int64_t{5'000'000} * k,
                      Eigen::Vector3d(1e-3, -2e-3, 3e-4) * (1.0 + 0.1 * k) / 3.0,
                      Eigen::Vector3d(0.026, 0.037, -0.019) * (1.0 - 0.01 * k) / 7.0});
  }
  WriteImuBiasCsv(OutPath("imu_bias.csv"), biases);
  const std::vector<std::string> lines = Lines(ReadText(OutPath("imu_bias.csv")));
  EXPECT_EQ(lines[0], "t_ns,bgx,bgy,bgz,bax,bay,baz");
  const ImuBiasTrajectory read = ReadImuBiasCsv(OutPath("imu_bias.csv"));
  ASSERT_EQ(read.size(), biases.size());
  for (size_t i = 0; i < read.size(); ++i) {
    EXPECT_EQ(read[i].t_ns, biases[i].t_ns) << i;
    EXPECT_EQ(read[i].b_g, biases[i].b_g) << i;
    EXPECT_EQ(read[i].b_a, biases[i].b_a) << i;
  }
  WriteText(OutPath("imu_bias_bad.csv"), ReplaceField(lines, 3, 5, "0.0x1"));
  ExpectParseError(OutPath("imu_bias_bad.csv"), [](const std::string& p) { ReadImuBiasCsv(p); },
                   {3, FieldColumn(lines[2], 5), "number"});
}

TEST(CsvFilesTest, TrajectoryQuaternionNotUnit) {
  WriteTrajectoryCsv(OutPath("traj_ref.csv"), test_data::MakeDrive(1.0).trajectory);
  const std::vector<std::string> lines = Lines(ReadText(OutPath("traj_ref.csv")));
  // qw of the first pose is 1 (yaw 0): 1.01 is a quaternion of norm 1.01.
  WriteText(OutPath("traj_bad_q.csv"), ReplaceField(lines, 2, 7, "1.01"));
  ExpectParseError(OutPath("traj_bad_q.csv"), [](const std::string& p) { ReadTrajectoryCsv(p); },
                   {2, FieldColumn(lines[1], 4), "norm 1.01"});
  // Off by 1e-4 (rounded digits) is normalized, not rejected.
  WriteText(OutPath("traj_rounded_q.csv"), ReplaceField(lines, 2, 7, "1.0001"));
  const Trajectory read = ReadTrajectoryCsv(OutPath("traj_rounded_q.csv"));
  EXPECT_NEAR(read[0].T_W_I.q.norm(), 1.0, 1e-15);
}

TEST(CsvFilesTest, MissingSweepFile) {
  const std::string directory = test::OutputDir("csv_files/sweeps").string();
  WriteText(directory + "/100.ply", "ply\n");
  WriteLidarCsv(OutPath("lidar_missing.csv"), {{100, "100.ply"}, {200, "200.ply"}});
  ExpectParseError(OutPath("lidar_missing.csv"),
                   [&](const std::string& p) { ReadLidarCsv(p, directory); },
                   {3, 5, "sweep file '200.ply' not found"});
}

// A sweep file LoadSweep cannot read (neither .ply nor .pcd) is named with its lidar.csv line
// when the dataset is read, not halfway through a run.
TEST(CsvFilesTest, SweepFileOfAnotherFormat) {
  const std::string directory = test::OutputDir("csv_files/bin_sweeps").string();
  WriteText(directory + "/100.PLY", "ply\n");
  WriteText(directory + "/200.bin", "raw");
  WriteText(OutPath("lidar_bin.csv"), "t_ns,file\n100,100.PLY\n200,200.bin\n");
  ExpectParseError(OutPath("lidar_bin.csv"),
                   [&](const std::string& p) { ReadLidarCsv(p, directory); },
                   {3, 5, "sweep file '200.bin' is neither .ply nor .pcd"});
}

// A stamp beyond 2^62 ns of 1970: the differences between stamps would pass int64.
TEST(CsvFilesTest, StampFarFromAnyTime) {
  WriteText(OutPath("far_stamp.csv"), ReplaceField(ImuLines(), 3, 0, "5000000000000000000"));
  ExpectParseError(OutPath("far_stamp.csv"), kReadImu,
                   {3, 1, "timestamp 5000000000000000000 ns is more than 146 years from 1970"});
}

TEST(CsvFilesTest, WheelRateInRpm) {
  sensors::WheelSamples wheel = test_data::MakeDrive(1.0).wheel;
  for (sensors::WheelSample& w : wheel) w.right_rad_s *= 60.0 / (2.0 * M_PI) * 60.0;
  WriteWheelCsv(OutPath("wheel_rpm.csv"), wheel);
  const std::vector<std::string> lines = Lines(ReadText(OutPath("wheel_rpm.csv")));
  ExpectParseError(OutPath("wheel_rpm.csv"), [](const std::string& p) { ReadWheelCsv(p); },
                   {2, FieldColumn(lines[1], 2), "rpm or deg/s"});
}

TEST(CsvFilesTest, GnssLatitudeOutOfRange) {
  WriteGnssCsv(OutPath("gnss_ref.csv"), test_data::MakeDrive(1.0).gnss);
  const std::vector<std::string> lines = Lines(ReadText(OutPath("gnss_ref.csv")));
  WriteText(OutPath("gnss_lat.csv"), ReplaceField(lines, 4, 1, "148.1"));
  ExpectParseError(OutPath("gnss_lat.csv"), [](const std::string& p) { ReadGnssCsv(p); },
                   {4, FieldColumn(lines[3], 1), "latitude"});
}

// ---- stamps in microseconds ----

// The reference drive's samples with their stamps divided by 1000: microseconds.
template <typename Samples>
Samples InMicroseconds(Samples samples) {
  for (auto& sample : samples) sample.t_ns /= 1000;
  return samples;
}

TEST(CsvFilesTest, WheelStampsInMicroseconds) {
  WriteWheelCsv(OutPath("wheel_us.csv"), InMicroseconds(test_data::MakeDrive(1.0).wheel));
  ExpectParseError(OutPath("wheel_us.csv"), [](const std::string& p) { ReadWheelCsv(p); },
                   {3, 1,
                    "t_ns: the median interval between rows is 10000 ns, a wheel encoder at "
                    "100000 Hz, beyond any (limit 10000 Hz): the stamps seem to be in "
                    "microseconds; autocal expects nanoseconds"});
  // In nanoseconds the same file reads.
  WriteWheelCsv(OutPath("wheel_ns.csv"), test_data::MakeDrive(1.0).wheel);
  EXPECT_EQ(ReadWheelCsv(OutPath("wheel_ns.csv")).size(), 101u);
}

TEST(CsvFilesTest, ImuGnssAndLidarStampsInMicroseconds) {
  const test_data::Drive drive = test_data::MakeDrive(2.0);
  WriteImuCsv(OutPath("imu_us.csv"), InMicroseconds(drive.imu));
  ExpectParseError(OutPath("imu_us.csv"), kReadImu,
                   {3, 1,
                    "an IMU at 200000 Hz, beyond any (limit 10000 Hz): the stamps seem to "
                    "be in microseconds"});
  WriteGnssCsv(OutPath("gnss_us.csv"), InMicroseconds(drive.gnss));
  ExpectParseError(OutPath("gnss_us.csv"), [](const std::string& p) { ReadGnssCsv(p); },
                   {3, 1, "a GNSS receiver at 10000 Hz, beyond any (limit 200 Hz)"});
  std::vector<LidarSweepRef> sweeps;
  for (int i = 0; i < 20; ++i)
    sweeps.push_back({(test_data::kStartNs + i * 100'000'000) / 1000, std::to_string(i) + ".ply"});
  WriteLidarCsv(OutPath("lidar_us.csv"), sweeps);
  ExpectParseError(OutPath("lidar_us.csv"), [](const std::string& p) { ReadLidarCsv(p); },
                   {3, 1, "a LiDAR at 10000 Hz, beyond any (limit 1000 Hz)"});
}

// ---- a gyroscope in deg/s on a drive that never turns fast ----

// `still_s` at rest (gyro noise of a MEMS IMU, 0.002 rad/s per axis unless given, and a bias), then
// a straight drive with gentle swerves (|omega| <= 0.04 rad/s) and vibration, at 200 Hz; the gyro
// multiplied by `gyro_scale` (180 / pi: logged in deg/s).
sensors::ImuSamples GentleDrive(double still_s, double gyro_scale,
                                double gyro_noise_rad_s = 0.002) {
  std::mt19937 rng(11);
  std::normal_distribution<double> gyro_noise(0.0, gyro_noise_rad_s);
  std::normal_distribution<double> accel_noise(0.0, 0.01);
  std::normal_distribution<double> vibration(0.0, 0.3);
  const Eigen::Vector3d bias(0.003, -0.002, 0.001);
  sensors::ImuSamples imu;
  for (int i = 0; i <= 200 * 12; ++i) {
    const double t = 0.005 * i;
    const bool moving = t >= still_s;
    sensors::ImuSample s;
    s.t_ns = test_data::kStartNs + int64_t{5'000'000} * i;
    Eigen::Vector3d omega = bias;
    if (moving) omega.z() += 0.04 * std::sin(0.5 * (t - still_s));
    for (int a = 0; a < 3; ++a) omega[a] += gyro_noise(rng);
    s.gyro_rad_s = gyro_scale * omega;
    s.accel_m_s2 = Eigen::Vector3d(0.0, 0.0, test_data::kGravity);
    for (int a = 0; a < 3; ++a) s.accel_m_s2[a] += moving ? vibration(rng) : accel_noise(rng);
    imu.push_back(s);
  }
  return imu;
}

TEST(CsvFilesTest, GyroInDegreesPerSecondOnADriveThatNeverTurnsFast) {
  WriteImuCsv(OutPath("gentle_rad_s.csv"), GentleDrive(2.0, 1.0));
  EXPECT_NO_THROW(ReadImuCsv(OutPath("gentle_rad_s.csv")));
  // In deg/s the 99th percentile of |omega| stays below 3 (the drive never turns fast): the
  // still start tells.
  WriteImuCsv(OutPath("gentle_deg_s.csv"), GentleDrive(2.0, kRadToDeg));
  const std::vector<std::string> lines = Lines(ReadText(OutPath("gentle_deg_s.csv")));
  ExpectParseError(OutPath("gentle_deg_s.csv"), kReadImu,
                   {2, FieldColumn(lines[1], 1),
                    "gyroscope seems to be in deg/s, autocal expects rad/s: from this row the "
                    "accelerometer is steady for "});
  // Switched off, the file reads.
  ImuPlausibilityOptions checks;
  checks.check_gyro_unit_at_rest = false;
  EXPECT_NO_THROW(ReadImuCsv(OutPath("gentle_deg_s.csv"), checks));
}

// A noisy gyro in rad/s (0.03 rad/s per sample) scatters at rest like a good one in deg/s:
// the noise sensors.yaml states tells them apart.
TEST(CsvFilesTest, ANoisyGyroIsNotTakenForDegreesPerSecond) {
  WriteImuCsv(OutPath("noisy_rad_s.csv"), GentleDrive(2.0, 1.0, 0.03));
  ImuPlausibilityOptions checks;
  checks.gyroscope_noise_density = 0.03 / std::sqrt(checks.update_rate_hz);
  EXPECT_NO_THROW(ReadImuCsv(OutPath("noisy_rad_s.csv"), checks));
  // Stated 15 times better than it is, the same log looks like deg/s.
  checks.gyroscope_noise_density /= 15.0;
  EXPECT_THROW(ReadImuCsv(OutPath("noisy_rad_s.csv"), checks), ParseError);
}

TEST(CsvFilesTest, ASteadyTurnIsNotTakenForDegreesPerSecond) {
  // No still start: a steady 0.3 rad/s turn from the first sample on a smooth road. The
  // accelerometer is steady and the gyro fails the still test on its mean; read as deg/s it
  // would pass, but its scatter is a rad/s gyro's.
  sensors::ImuSamples imu = GentleDrive(100.0, 1.0);
  for (sensors::ImuSample& s : imu) s.gyro_rad_s.z() += 0.3;
  WriteImuCsv(OutPath("steady_turn.csv"), imu);
  EXPECT_NO_THROW(ReadImuCsv(OutPath("steady_turn.csv")));
}

TEST(CsvFilesTest, ATurnOnTheSpotIsNotTakenForDegreesPerSecond) {
  // A robot spinning on the spot about the gravity axis, its rate growing 0 -> 1.2 rad/s over
  // the first 4 s: the accelerometer is steady and the gyro's scatter, read as deg/s, is that
  // of a still gyro; but it changes smoothly from sample to sample, as no noise does.
  sensors::ImuSamples imu = GentleDrive(100.0, 1.0);
  for (size_t i = 0; i < imu.size(); ++i) {
    imu[i].gyro_rad_s.z() += std::min(1.2, 0.3 * 0.005 * static_cast<double>(i));
  }
  WriteImuCsv(OutPath("spin.csv"), imu);
  EXPECT_NO_THROW(ReadImuCsv(OutPath("spin.csv")));
}

TEST(CsvFilesTest, WritersRefuseWhatReadersReject) {
  sensors::ImuSamples imu = test_data::MakeDrive(1.0).imu;
  imu[3].accel_m_s2.x() = std::nan("");
  EXPECT_THROW(WriteImuCsv(OutPath("w_nan.csv"), imu), Error);
  imu = test_data::MakeDrive(1.0).imu;
  imu[5].t_ns = imu[4].t_ns;
  EXPECT_THROW(WriteImuCsv(OutPath("w_dup.csv"), imu), Error);
  EXPECT_THROW(WriteLidarCsv(OutPath("w_name.csv"), {{1, "../escape.ply"}}), Error);
}

// ---- wheel forms: linear speeds and the controller's twist ----

namespace wheel_forms {

// The reference drive's wheel rates as rear-wheel speeds (radius 0.33 m), with a front pair
// when `four_wheels`: digits that need all 17 places.
sensors::WheelSpeedSamples DriveSpeeds(double duration_s, bool four_wheels) {
  sensors::WheelSpeedSamples out;
  for (const sensors::WheelSample& w : test_data::MakeDrive(duration_s).wheel) {
    sensors::WheelSpeedSample s;
    s.t_ns = w.t_ns;
    s.left_m_s = 0.33 * w.left_rad_s;
    s.right_m_s = 0.33 * w.right_rad_s;
    s.has_front = four_wheels;
    if (four_wheels) {
      s.front_left_m_s = s.left_m_s * (1.0 + 1.0 / 3.0 * 1e-3);
      s.front_right_m_s = s.right_m_s / 3.0 * 2.99;
    }
    out.push_back(s);
  }
  return out;
}

sensors::OdometrySamples DriveTwist(double duration_s) {
  sensors::OdometrySamples out;
  for (const sensors::WheelSample& w : test_data::MakeDrive(duration_s).wheel) {
    out.push_back({w.t_ns, 0.33 * 0.5 * (w.left_rad_s + w.right_rad_s),
                   0.33 * (w.right_rad_s - w.left_rad_s) / 1.6});
  }
  return out;
}

const auto kReadSpeeds = [](const std::string& p) { ReadWheelSpeedCsv(p); };
const auto kReadOdometry = [](const std::string& p) { ReadOdometryCsv(p); };

}  // namespace wheel_forms

TEST(CsvFilesTest, WheelSpeedsOfTwoAndFourWheelsRoundTripExactly) {
  for (bool four_wheels : {false, true}) {
    const sensors::WheelSpeedSamples written = wheel_forms::DriveSpeeds(2.0, four_wheels);
    const std::string path = OutPath(four_wheels ? "speed4.csv" : "speed2.csv");
    WriteWheelSpeedCsv(path, written);
    EXPECT_EQ(Lines(ReadText(path))[0],
              four_wheels ? "t_ns,left_m_s,right_m_s,front_left_m_s,front_right_m_s"
                          : "t_ns,left_m_s,right_m_s");
    const sensors::WheelSpeedSamples read = ReadWheelSpeedCsv(path);
    ASSERT_EQ(read.size(), written.size());
    for (size_t i = 0; i < read.size(); ++i) {
      ASSERT_EQ(read[i].t_ns, written[i].t_ns) << "row " << i;
      ASSERT_EQ(read[i].left_m_s, written[i].left_m_s) << "row " << i;
      ASSERT_EQ(read[i].right_m_s, written[i].right_m_s) << "row " << i;
      ASSERT_EQ(read[i].has_front, four_wheels) << "row " << i;
      ASSERT_EQ(read[i].front_left_m_s, written[i].front_left_m_s) << "row " << i;
      ASSERT_EQ(read[i].front_right_m_s, written[i].front_right_m_s) << "row " << i;
    }
  }
  // One layout per file.
  sensors::WheelSpeedSamples mixed = wheel_forms::DriveSpeeds(1.0, true);
  mixed[3].has_front = false;
  EXPECT_THROW(WriteWheelSpeedCsv(OutPath("mixed.csv"), mixed), Error);
}

TEST(CsvFilesTest, OdometryRoundTripsExactly) {
  const sensors::OdometrySamples written = wheel_forms::DriveTwist(2.0);
  WriteOdometryCsv(OutPath("odometry.csv"), written);
  const sensors::OdometrySamples read = ReadOdometryCsv(OutPath("odometry.csv"));
  ASSERT_EQ(read.size(), written.size());
  for (size_t i = 0; i < read.size(); ++i) {
    ASSERT_EQ(read[i].t_ns, written[i].t_ns) << "row " << i;
    ASSERT_EQ(read[i].speed_m_s, written[i].speed_m_s) << "row " << i;
    ASSERT_EQ(read[i].yaw_rate_rad_s, written[i].yaw_rate_rad_s) << "row " << i;
  }
}

// Each bad input is one error with its line and column and what was expected.
TEST(CsvFilesTest, WheelFormFilesNameLineColumnAndExpectation) {
  WriteWheelSpeedCsv(OutPath("speed_ref.csv"), wheel_forms::DriveSpeeds(1.0, true));
  const std::vector<std::string> speed = Lines(ReadText(OutPath("speed_ref.csv")));
  // A front column misnamed: the four-wheel header is checked column by column.
  std::vector<std::string> renamed = speed;
  renamed[0] = "t_ns,left_m_s,right_m_s,front_l_m_s,front_right_m_s";
  WriteText(OutPath("speed_header.csv"), JoinLines(renamed));
  ExpectParseError(OutPath("speed_header.csv"), wheel_forms::kReadSpeeds,
                   {1, FieldColumn(renamed[0], 3), "expected 'front_left_m_s'"});
  // A row with the rear pair only in a four-wheel file.
  std::vector<std::string> short_row = speed;
  short_row[2] = short_row[2].substr(0, FieldColumn(short_row[2], 3) - 2);
  WriteText(OutPath("speed_short.csv"), JoinLines(short_row));
  ExpectParseError(OutPath("speed_short.csv"), wheel_forms::kReadSpeeds,
                   {3, static_cast<int64_t>(short_row[2].size()) + 1, "expected 5 columns"});
  // km/h instead of m/s.
  WriteText(OutPath("speed_kmh.csv"), ReplaceField(speed, 4, 2, "130.5"));
  ExpectParseError(OutPath("speed_kmh.csv"), wheel_forms::kReadSpeeds,
                   {4, FieldColumn(speed[3], 2), "km/h or mph"});

  WriteOdometryCsv(OutPath("odometry_ref.csv"), wheel_forms::DriveTwist(1.0));
  const std::vector<std::string> odometry = Lines(ReadText(OutPath("odometry_ref.csv")));
  WriteText(OutPath("odometry_deg.csv"), ReplaceField(odometry, 5, 2, "28.6"));
  ExpectParseError(OutPath("odometry_deg.csv"), wheel_forms::kReadOdometry,
                   {5, FieldColumn(odometry[4], 2), "deg/s"});
  WriteText(OutPath("odometry_text.csv"), ReplaceField(odometry, 3, 1, "fast"));
  ExpectParseError(OutPath("odometry_text.csv"), wheel_forms::kReadOdometry,
                   {3, FieldColumn(odometry[2], 1), "speed_m_s: expected a number"});
  std::vector<std::string> wrong = odometry;
  wrong[0] = "t_ns,v_m_s,yaw_rate_rad_s";
  WriteText(OutPath("odometry_header.csv"), JoinLines(wrong));
  ExpectParseError(OutPath("odometry_header.csv"), wheel_forms::kReadOdometry,
                   {1, 6, "expected 'speed_m_s'"});
  WriteOdometryCsv(OutPath("odometry_us.csv"), InMicroseconds(wheel_forms::DriveTwist(1.0)));
  ExpectParseError(OutPath("odometry_us.csv"), wheel_forms::kReadOdometry,
                   {3, 1, "the stamps seem to be in microseconds"});
}

}  // namespace
}  // namespace io
}  // namespace autocal
