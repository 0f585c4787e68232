#include "autocal/io/calibration_yaml.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdint>
#include <fstream>
#include <iostream>
#include <iterator>
#include <string>

#include "autocal/common/error.h"
#include "autocal/common/units.h"
#include "autocal/io/sensors_yaml.h"
#include "io/io_test_data.h"
#include "io/prefix_check.h"
#include "support/test_paths.h"

namespace autocal {
namespace io {
namespace {

using ::testing::HasSubstr;

std::string OutPath(const std::string& name) {
  return (test::OutputDir("calibration_yaml") / name).string();
}

void WriteText(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << text;
}

// A result as a calibration run would write it: values with digits that need all 17
// significant places, sigmas, observability of every form, solver and residual maps.
CalibrationFile FullResult() {
  CalibrationFile file;
  file.value = test_data::TrueCalibration();
  file.value.time_offset_lidar_imu_s = 1.0 / 3.0 * 0.01;
  CalibrationUncertainty& u = file.uncertainty;
  u.T_I_L.sigma_rot_deg = Eigen::Vector3d(0.01, 0.02, 1.0 / 7.0);
  u.T_I_L.sigma_p_m = Eigen::Vector3d(0.001, 0.002, 0.3);
  u.T_I_L.observable = {true, true, true, true, true, false};
  u.time_offset_lidar_imu_s = {0.0004, true};
  u.wheel_radius_left_m.sigma = 1e-4;
  u.wheel_radius_right_m.observable = false;
  u.p_I_A_m.sigma = Eigen::Vector3d(0.01, 0.01, 0.02);
  u.p_I_A_m.observable = {true};
  u.T_I_V.observable = {false};
  file.value.wheel_speed_scale_left = 1.0 + 1.0 / 3.0 * 1e-2;
  file.value.wheel_speed_scale_right = 0.987;
  file.value.odometry_speed_scale = 0.9612345678901234;
  file.value.effective_track_m = 0.8123;
  u.wheel_speed_scale_left.sigma = 2e-4;
  u.odometry_speed_scale = {1.0 / 7.0 * 1e-3, true};
  u.effective_track_m.observable = false;
  file.value.time_offset_wheel_imu_s = -0.391 - 1.0 / 3.0 * 1e-3;
  file.value.time_offset_gnss_imu_s = 0.15;
  u.time_offset_wheel_imu_s = {1.0 / 7.0 * 1e-2, true};
  u.time_offset_gnss_imu_s.observable = false;
  file.solver = {{"termination", "CONVERGENCE"},
                 {"iterations", "14"},
                 {"message", "Function tolerance reached: |cost change| < 1e-6"},
                 {"flag", "yes"}};
  file.residuals["lidar"] = {{"rms_m", 0.0213}, {"count", 123456}};
  file.residuals["imu"] = {{"chi2_per_dof", 1.0 / 3.0}};
  file.residuals["gnss"] = {};
  return file;
}

void ExpectSameCalibration(const sensors::Calibration& a, const sensors::Calibration& b) {
  EXPECT_EQ(a.q_I_L.coeffs(), b.q_I_L.coeffs())
      << a.q_I_L.coeffs().transpose() << " vs " << b.q_I_L.coeffs().transpose();
  EXPECT_EQ(a.p_I_L, b.p_I_L) << a.p_I_L.transpose() << " vs " << b.p_I_L.transpose();
  EXPECT_EQ(a.time_offset_lidar_imu_s, b.time_offset_lidar_imu_s);
  EXPECT_EQ(a.q_I_V.coeffs(), b.q_I_V.coeffs())
      << a.q_I_V.coeffs().transpose() << " vs " << b.q_I_V.coeffs().transpose();
  EXPECT_EQ(a.p_I_V, b.p_I_V) << a.p_I_V.transpose() << " vs " << b.p_I_V.transpose();
  EXPECT_EQ(a.wheel_radius_left_m, b.wheel_radius_left_m);
  EXPECT_EQ(a.wheel_radius_right_m, b.wheel_radius_right_m);
  EXPECT_EQ(a.track_width_m, b.track_width_m);
  EXPECT_EQ(a.p_I_A, b.p_I_A) << a.p_I_A.transpose() << " vs " << b.p_I_A.transpose();
  EXPECT_EQ(a.wheel_speed_scale_left, b.wheel_speed_scale_left);
  EXPECT_EQ(a.wheel_speed_scale_right, b.wheel_speed_scale_right);
  EXPECT_EQ(a.odometry_speed_scale, b.odometry_speed_scale);
  EXPECT_EQ(a.effective_track_m, b.effective_track_m);
  EXPECT_EQ(a.time_offset_wheel_imu_s, b.time_offset_wheel_imu_s);
  EXPECT_EQ(a.time_offset_gnss_imu_s, b.time_offset_gnss_imu_s);
}

void ExpectSamePose(const PoseBlockInfo& a, const PoseBlockInfo& b) {
  EXPECT_EQ(a.sigma_rot_deg.has_value(), b.sigma_rot_deg.has_value());
  if (a.sigma_rot_deg && b.sigma_rot_deg) {
    EXPECT_EQ(*a.sigma_rot_deg, *b.sigma_rot_deg);
  }
  EXPECT_EQ(a.sigma_p_m.has_value(), b.sigma_p_m.has_value());
  if (a.sigma_p_m && b.sigma_p_m) {
    EXPECT_EQ(*a.sigma_p_m, *b.sigma_p_m);
  }
  EXPECT_EQ(a.observable, b.observable);
}

void ExpectSameScalar(const ScalarBlockInfo& a, const ScalarBlockInfo& b) {
  EXPECT_EQ(a.sigma, b.sigma);
  EXPECT_EQ(a.observable, b.observable);
}

TEST(CalibrationYamlTest, ResultRoundTripsExactly) {
  const CalibrationFile written = FullResult();
  WriteCalibrationYaml(OutPath("result.yaml"), written);
  const CalibrationFile read = ReadCalibrationYaml(OutPath("result.yaml"));
  ExpectSameCalibration(read.value, written.value);
  ExpectSamePose(read.uncertainty.T_I_L, written.uncertainty.T_I_L);
  ExpectSamePose(read.uncertainty.T_I_V, written.uncertainty.T_I_V);
  ExpectSameScalar(read.uncertainty.time_offset_lidar_imu_s,
                   written.uncertainty.time_offset_lidar_imu_s);
  ExpectSameScalar(read.uncertainty.wheel_radius_left_m, written.uncertainty.wheel_radius_left_m);
  ExpectSameScalar(read.uncertainty.wheel_radius_right_m, written.uncertainty.wheel_radius_right_m);
  ExpectSameScalar(read.uncertainty.track_width_m, written.uncertainty.track_width_m);
  ExpectSameScalar(read.uncertainty.wheel_speed_scale_left,
                   written.uncertainty.wheel_speed_scale_left);
  ExpectSameScalar(read.uncertainty.wheel_speed_scale_right,
                   written.uncertainty.wheel_speed_scale_right);
  ExpectSameScalar(read.uncertainty.odometry_speed_scale, written.uncertainty.odometry_speed_scale);
  ExpectSameScalar(read.uncertainty.effective_track_m, written.uncertainty.effective_track_m);
  ExpectSameScalar(read.uncertainty.time_offset_wheel_imu_s,
                   written.uncertainty.time_offset_wheel_imu_s);
  ExpectSameScalar(read.uncertainty.time_offset_gnss_imu_s,
                   written.uncertainty.time_offset_gnss_imu_s);
  ASSERT_TRUE(read.uncertainty.p_I_A_m.sigma.has_value());
  EXPECT_EQ(*read.uncertainty.p_I_A_m.sigma, *written.uncertainty.p_I_A_m.sigma);
  EXPECT_EQ(read.uncertainty.p_I_A_m.observable, written.uncertainty.p_I_A_m.observable);
  EXPECT_EQ(read.solver, written.solver);
  EXPECT_EQ(read.residuals, written.residuals);
}

TEST(CalibrationYamlTest, HandWrittenShortForms) {
  WriteText(OutPath("short.yaml"),
            "T_I_L: {q_xyzw: [0, 0, 0.7071068, 0.7071068], p_m: [1, 2, 3]}\n"
            "time_offset_lidar_imu_s: -0.01\n"
            "p_I_A_m: [0.5, 0, 1.5]\n");
  const CalibrationFile read = ReadCalibrationYaml(OutPath("short.yaml"));
  EXPECT_NEAR(read.value.q_I_L.norm(), 1.0, 1e-15);
  EXPECT_NEAR(read.value.q_I_L.angularDistance(
                  Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()))),
              0.0, 1e-6);
  EXPECT_EQ(read.value.time_offset_lidar_imu_s, -0.01);
  EXPECT_EQ(read.value.p_I_A, Eigen::Vector3d(0.5, 0, 1.5));
  // Blocks not in the file keep the defaults.
  EXPECT_EQ(read.value.track_width_m, sensors::Calibration().track_width_m);
}

TEST(CalibrationYamlTest, SensorsYamlRoundTripsExactly) {
  const test_data::Drive drive = test_data::MakeDrive(0.5);
  SensorsConfig config = drive.config;
  config.imu.noise.gyroscope_noise_density = 1.0 / 3.0 * 1e-3;
  config.imu.gravity_m_s2 = 9.81;
  config.nominal_uncertainty.T_I_L.sigma_p_m = Eigen::Vector3d(0.1, 0.1, 0.2);
  config.lidar->num_beams = 64;
  config.wheel->noise_rad_s = 0.05;
  config.wheel->form = sensors::WheelForm::kSpeedYawRate;
  config.wheel->noise_m_s = 1.0 / 3.0 * 0.1;
  config.wheel->yaw_rate_noise_rad_s = 0.07;
  config.wheel->controller_track_m = 0.5555;
  config.wheel->lateral_slip_sigma_m_s = 1.0 / 3.0 * 0.01;
  config.wheel->cornering_compliance_rad_per_m_s2 = 0.3 * kDegToRad;
  config.gnss->rate_hz = 5.0;
  WriteSensorsYaml(OutPath("sensors.yaml"), config);
  const SensorsConfig read = ReadSensorsYaml(OutPath("sensors.yaml"));
  EXPECT_EQ(read.imu.noise.gyroscope_noise_density, config.imu.noise.gyroscope_noise_density);
  EXPECT_EQ(read.imu.noise.gyroscope_random_walk, config.imu.noise.gyroscope_random_walk);
  EXPECT_EQ(read.imu.noise.accelerometer_noise_density,
            config.imu.noise.accelerometer_noise_density);
  EXPECT_EQ(read.imu.noise.accelerometer_random_walk, config.imu.noise.accelerometer_random_walk);
  EXPECT_EQ(read.imu.noise.update_rate_hz, config.imu.noise.update_rate_hz);
  EXPECT_EQ(read.imu.gravity_m_s2, config.imu.gravity_m_s2);
  ASSERT_TRUE(read.lidar && read.wheel && read.gnss);
  EXPECT_EQ(read.lidar->num_beams, 64);
  EXPECT_EQ(read.lidar->min_elevation_deg, config.lidar->min_elevation_deg);
  EXPECT_EQ(read.lidar->max_elevation_deg, config.lidar->max_elevation_deg);
  EXPECT_EQ(read.lidar->azimuth_resolution_deg, config.lidar->azimuth_resolution_deg);
  EXPECT_EQ(read.lidar->min_range_m, config.lidar->min_range_m);
  EXPECT_EQ(read.lidar->max_range_m, config.lidar->max_range_m);
  EXPECT_EQ(read.lidar->range_noise_m, config.lidar->range_noise_m);
  EXPECT_EQ(read.lidar->rate_hz, config.lidar->rate_hz);
  EXPECT_EQ(read.wheel->noise_rad_s, 0.05);
  EXPECT_EQ(read.wheel->rate_hz, config.wheel->rate_hz);
  EXPECT_EQ(read.wheel->form, sensors::WheelForm::kSpeedYawRate);
  EXPECT_EQ(read.wheel->noise_m_s, config.wheel->noise_m_s);
  EXPECT_EQ(read.wheel->yaw_rate_noise_rad_s, 0.07);
  EXPECT_EQ(read.wheel->controller_track_m, 0.5555);
  EXPECT_EQ(read.wheel->lateral_slip_sigma_m_s, config.wheel->lateral_slip_sigma_m_s);
  EXPECT_EQ(read.wheel->cornering_compliance_rad_per_m_s2,
            config.wheel->cornering_compliance_rad_per_m_s2);
  EXPECT_EQ(read.gnss->rate_hz, 5.0);
  ExpectSameCalibration(read.nominal_calibration, config.nominal_calibration);
  ExpectSamePose(read.nominal_uncertainty.T_I_L, config.nominal_uncertainty.T_I_L);
}

TEST(CalibrationYamlTest, SensorsYamlAcceptsPastedKalibrImuYaml) {
  WriteText(OutPath("kalibr.yaml"),
            "imu:\n"
            "  #Accelerometers\n"
            "  accelerometer_noise_density: 1.86e-03\n"
            "  accelerometer_random_walk: 4.33e-04\n"
            "  #Gyroscopes\n"
            "  gyroscope_noise_density: 1.87e-04\n"
            "  gyroscope_random_walk: 2.66e-05\n"
            "  rostopic: /imu0\n"
            "  update_rate: 200.0\n");
  const SensorsConfig read = ReadSensorsYaml(OutPath("kalibr.yaml"));
  EXPECT_EQ(read.imu.noise.accelerometer_noise_density, 1.86e-03);
  EXPECT_EQ(read.imu.noise.gyroscope_random_walk, 2.66e-05);
  EXPECT_FALSE(read.lidar.has_value());
}

// ---- bad input ----

template <typename Read>
void ExpectParseError(const std::string& name, const std::string& text, Read read, int64_t line,
                      int64_t column, const std::string& message) {
  const std::string path = OutPath(name);
  WriteText(path, text);
  try {
    read(path);
    ADD_FAILURE() << "no ParseError for " << name << ":\n" << text;
  } catch (const ParseError& e) {
    EXPECT_EQ(e.location().file, path);
    EXPECT_EQ(e.location().line, line) << e.what();
    EXPECT_EQ(e.location().column, column) << e.what();
    EXPECT_THAT(e.detail(), HasSubstr(message)) << e.what();
  }
}

const auto kReadCalibration = [](const std::string& path) { ReadCalibrationYaml(path); };
const auto kReadSensors = [](const std::string& path) { ReadSensorsYaml(path); };

// 1-based column of the first `token` in line `line` (1-based) of `text`.
int64_t ColumnOf(const std::string& text, int line, const std::string& token) {
  size_t start = 0;
  for (int i = 1; i < line; ++i) start = text.find('\n', start) + 1;
  return static_cast<int64_t>(text.find(token, start) - start) + 1;
}

TEST(CalibrationYamlTest, UnknownKeys) {
  const std::string top = "T_I_L: {q_xyzw: [0, 0, 0, 1], p_m: [0, 0, 0]}\ntrack_widht_m: 1.6\n";
  ExpectParseError("typo_top.yaml", top, kReadCalibration, 2, 1, "unknown key 'track_widht_m'");
  const std::string block =
      "T_I_L:\n  q_xyzw: [0, 0, 0, 1]\n  p_m: [0, 0, 0]\n  sigma_rot: [1, 1, 1]\n";
  ExpectParseError("typo_block.yaml", block, kReadCalibration, 4, ColumnOf(block, 4, "sigma_rot"),
                   "T_I_L: unknown key 'sigma_rot'");
  const std::string sensors =
      "imu:\n  gyroscope_noise_density: 1e-4\n  gyroscope_random_walk: 1e-5\n"
      "  accelerometer_noise_density: 1e-3\n  accelerometer_random_walk: 1e-3\n"
      "  update_rate: 200\n  gravity: 9.81\n";
  ExpectParseError("typo_sensors.yaml", sensors, kReadSensors, 7, ColumnOf(sensors, 7, "gravity"),
                   "imu: unknown key 'gravity'");
}

TEST(CalibrationYamlTest, DuplicateKey) {
  ExpectParseError("duplicate.yaml", "track_width_m: 1.6\ntrack_width_m: 1.7\n", kReadCalibration,
                   2, 1, "'track_width_m' appears twice");
}

TEST(CalibrationYamlTest, WrongTypes) {
  struct Case {
    std::string text;
    std::string token;  // where the error must point
    std::string message;
  };
  const Case cases[] = {
      {"track_width_m: {value: [1.6]}\n", "[1.6]",
       "track_width_m.value: expected a number, found a list"},
      {"T_I_L: {q_xyzw: [0, 0, zero, 1], p_m: [0, 0, 0]}\n", "zero",
       "T_I_L.q_xyzw[2]: expected a number, found 'zero'"},
      {"T_I_L: {q_xyzw: [0, 0, 0, 1], p_m: [0, 0]}\n", "[0, 0]}", "expected a list of 3 numbers"},
      {"time_offset_lidar_imu_s: {value: 0, observable: maybe}\n", "maybe",
       "expected true or false, found 'maybe'"},
      {"wheel_radius_left_m: .nan\n", ".nan", "expected a number, found '.nan'"},
      {"wheel_radius_left_m: 0.3x\n", "0.3x", "trailing characters 'x'"},
      {"wheel_radius_left_m: -0.3\n", "-0.3", "must be > 0"},
      {"residuals: {lidar: {rms_m: high}}\n", "high", "residuals.lidar.rms_m: expected a number"},
  };
  for (size_t i = 0; i < std::size(cases); ++i) {
    SCOPED_TRACE(cases[i].text);
    ExpectParseError("type_" + std::to_string(i) + ".yaml", cases[i].text, kReadCalibration, 1,
                     ColumnOf(cases[i].text, 1, cases[i].token), cases[i].message);
  }
}

TEST(CalibrationYamlTest, MissingRequiredKey) {
  const std::string pose = "T_I_L: {q_xyzw: [0, 0, 0, 1]}\n";
  ExpectParseError("missing.yaml", pose, kReadCalibration, 1, ColumnOf(pose, 1, "{"),
                   "T_I_L: missing required key 'p_m'");
  ExpectParseError("missing_imu.yaml", "imu:\n  gyroscope_noise_density: 1e-4\n", kReadSensors, 2,
                   3, "imu: missing required key 'gyroscope_random_walk'");
}

TEST(CalibrationYamlTest, QuaternionNotUnit) {
  const std::string text = "T_I_V: {q_xyzw: [0, 0, 0.1, 1], p_m: [0, 0, 0]}\n";
  ExpectParseError("not_unit.yaml", text, kReadCalibration, 1, ColumnOf(text, 1, "["),
                   "norm 1.00499");
}

TEST(CalibrationYamlTest, SyntaxErrorAndEmptyFile) {
  // The flow map of line 1 is never closed; yaml-cpp notices at the start of line 2.
  ExpectParseError("syntax.yaml",
                   "T_I_L: {q_xyzw: [0, 0, 0, 1], p_m: [0, 0, 0]\ntrack_width_m: 1\n",
                   kReadCalibration, 2, 1, "YAML syntax error: end of map flow not found");
  ExpectParseError("empty.yaml", "", kReadCalibration, 1, 1, "empty YAML document");
  // Two documents (two files joined): the second would be dropped, whatever it sets.
  ExpectParseError("two_documents.yaml",
                   "format: autocal_calibration_1\n---\ntime_offset_lidar_imu_s: {value: 1}\n",
                   kReadCalibration, 3, 1,
                   "a second YAML document (after '---'): the file must hold one");
}

// A written result states that it is whole: every proper prefix of it (a run stopped while
// writing, a disk that filled up) is refused with a ParseError naming the file, never read
// as a calibration whose missing blocks take their defaults. Before the format key and end
// line, 252 of the 1,954 prefixes of a real result parsed.
// A result written before the blocks of the other wheel forms and the wheel and GNSS clocks
// existed still reads: they keep their nominal defaults; a bad value in one of them is refused
// with its place.
TEST(CalibrationYamlTest, WheelFormBlocksAreOptionalInAResult) {
  const std::string path = OutPath("older.yaml");
  WriteCalibrationYaml(path, FullResult());
  std::ifstream in(path, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const size_t first = bytes.find("wheel_speed_scale_left:");
  const size_t after = bytes.find("solver:");
  ASSERT_NE(first, std::string::npos);
  WriteText(path, bytes.substr(0, first) + bytes.substr(after));
  const CalibrationFile read = ReadCalibrationYaml(path);
  EXPECT_EQ(read.value.odometry_speed_scale, 1.0);
  EXPECT_EQ(read.value.effective_track_m, sensors::Calibration().effective_track_m);
  EXPECT_EQ(read.value.track_width_m, FullResult().value.track_width_m);
  EXPECT_EQ(read.value.time_offset_wheel_imu_s, 0.0);
  EXPECT_EQ(read.value.time_offset_gnss_imu_s, 0.0);
  EXPECT_FALSE(read.uncertainty.time_offset_wheel_imu_s.sigma.has_value());
  ExpectParseError("bad_offset.yaml", "time_offset_gnss_imu_s: {value: .nan}\n", kReadCalibration,
                   1, 33, "time_offset_gnss_imu_s.value");
  ExpectParseError("bad_scale.yaml", "odometry_speed_scale: {value: -0.9}\n", kReadCalibration, 1,
                   31, "odometry_speed_scale.value");
}

TEST(CalibrationYamlTest, EveryPrefixOfAWrittenResultIsRefused) {
  const std::string path = OutPath("whole.yaml");
  WriteCalibrationYaml(path, FullResult());
  std::ifstream in(path, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  ASSERT_GT(bytes.size(), 1000u);
  EXPECT_NO_THROW(ReadCalibrationYaml(path));
  EXPECT_EQ(test_data::CountAcceptedPrefixes(bytes, OutPath("cut.yaml"),
                                             [](const std::string& p) { ReadCalibrationYaml(p); }),
            0u);
}

TEST(CalibrationYamlTest, AWrittenResultStatesItsFormatAndEnd) {
  const std::string path = OutPath("marked.yaml");
  WriteCalibrationYaml(path, FullResult());
  std::ifstream in(path, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_THAT(bytes, HasSubstr("\nformat: autocal_calibration_1\nT_I_L:"));
  EXPECT_THAT(bytes, ::testing::EndsWith("\n# end of autocal calibration\n"));
  // The end line is a comment: moving it elsewhere or dropping a block is a cut file too.
  const std::string without_end = bytes.substr(0, bytes.size() - 29);
  ExpectParseError("no_end.yaml", without_end, kReadCalibration, 0, 0,
                   "ends without its last line '# end of autocal calibration'");
  const size_t t_i_v = bytes.find("T_I_V:");
  const size_t after = bytes.find("solver:");
  ExpectParseError("no_t_i_v.yaml", bytes.substr(0, t_i_v) + bytes.substr(after), kReadCalibration,
                   3, 1, "block 'T_I_V' is missing");
  ExpectParseError("other_format.yaml",
                   "format: autocal_calibration_2\ntrack_width_m: 1.5\n# end of autocal "
                   "calibration\n",
                   kReadCalibration, 1, 9, "expected 'autocal_calibration_1'");
  // The schema embedded in sensors.yaml takes no format key.
  ExpectParseError("format_in_sensors.yaml",
                   "imu:\n  gyroscope_noise_density: 1e-4\n  gyroscope_random_walk: 1e-5\n"
                   "  accelerometer_noise_density: 1e-3\n  accelerometer_random_walk: 1e-3\n"
                   "  update_rate: 200\nnominal_calibration:\n  format: autocal_calibration_1\n",
                   kReadSensors, 8, 11, "only a calibration file has a format");
}

TEST(CalibrationYamlTest, ImplausibleSensorValues) {
  const std::string imu =
      "imu:\n  gyroscope_noise_density: 1e-4\n  gyroscope_random_walk: 1e-5\n"
      "  accelerometer_noise_density: 1e-3\n  accelerometer_random_walk: 1e-3\n  update_rate: "
      "200\n";
  const std::string gravity = imu + "  gravity_m_s2: 1.0\n";
  ExpectParseError("gravity_g.yaml", gravity, kReadSensors, 7, ColumnOf(gravity, 7, "1.0"),
                   "not Earth's gravity");
  ExpectParseError("lidar_elev.yaml",
                   imu + "lidar:\n  min_elevation_deg: 15\n  max_elevation_deg: -25\n",
                   kReadSensors, 8, 3, "min_elevation_deg < max_elevation_deg");
  ExpectParseError("results_in_sensors.yaml",
                   imu + "nominal_calibration:\n  solver: {iterations: 3}\n", kReadSensors, 8, 3,
                   "belong to results");
  ExpectParseError("no_imu.yaml", "gnss: {rate_hz: 10}\n", kReadSensors, 1, 1,
                   "sensors.yaml: missing required key 'imu'");
}

}  // namespace
}  // namespace io
}  // namespace autocal
