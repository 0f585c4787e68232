#include "autocal/io/problem_yaml.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "autocal/common/error.h"
#include "support/test_paths.h"

namespace autocal {
namespace io {
namespace {

using ::testing::HasSubstr;

std::string WriteProblem(const std::string& name, const std::string& text) {
  const std::string path = (test::OutputDir("problems") / name).string();
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << text;
  return path;
}

// 1-based column of the first `token` in line `line` (1-based) of `text`.
int64_t ColumnOf(const std::string& text, int line, const std::string& token) {
  size_t start = 0;
  for (int i = 1; i < line; ++i) start = text.find('\n', start) + 1;
  const size_t end = text.find('\n', start);
  const size_t at = text.substr(start, end - start).find(token);
  EXPECT_NE(at, std::string::npos) << "token '" << token << "' not on line " << line;
  return static_cast<int64_t>(at) + 1;
}

struct BadCase {
  std::string name;
  std::string text;
  int line;
  std::string token;  // the error points at its first occurrence on `line`
  std::string message;
};

void ExpectParseError(const BadCase& c) {
  const std::string path = WriteProblem(c.name + ".yaml", c.text);
  try {
    ReadProblemYaml(path);
    ADD_FAILURE() << "no ParseError for " << c.name << ":\n" << c.text;
  } catch (const ParseError& e) {
    EXPECT_EQ(e.location().file, path) << e.what();
    EXPECT_EQ(e.location().line, c.line) << c.name << ": " << e.what();
    EXPECT_EQ(e.location().column, ColumnOf(c.text, c.line, c.token)) << c.name << ": " << e.what();
    EXPECT_THAT(e.what(), HasSubstr(c.message)) << c.name;
  }
}

std::vector<std::filesystem::path> ProblemFiles() {
  std::vector<std::filesystem::path> files;
  for (const auto& entry : std::filesystem::directory_iterator(
           std::filesystem::path(AUTOCAL_SOURCE_DIR) / "problems")) {
    if (entry.path().extension() == ".yaml") files.push_back(entry.path());
  }
  std::sort(files.begin(), files.end());
  return files;
}

Problem ReadShipped(const std::string& name) {
  return ReadProblemYaml((std::filesystem::path(AUTOCAL_SOURCE_DIR) / "problems" / name).string());
}

bool Fixed(const VectorBlockSetting& s) { return s.mode == BlockMode::kFixed; }
bool Fixed(const ScalarBlockSetting& s) { return s.mode == BlockMode::kFixed; }

TEST(ProblemYamlTest, EveryShippedProblemParses) {
  const std::vector<std::filesystem::path> files = ProblemFiles();
  std::vector<std::string> names;
  for (const auto& file : files) {
    names.push_back(file.filename().string());
    SCOPED_TRACE(file.string());
    Problem problem;
    EXPECT_NO_THROW(problem = ReadProblemYaml(file.string()));
    EXPECT_EQ(problem.path, file.string());
    EXPECT_FALSE(problem.description.empty());
  }
  for (const char* expected :
       {"highway.yaml", "imu_wheel_gnss.yaml", "lidar_imu.yaml", "urban_full.yaml"}) {
    EXPECT_NE(std::find(names.begin(), names.end(), expected), names.end())
        << expected << " missing from problems/";
  }
}

TEST(ProblemYamlTest, ShippedProblemsSayWhatTheirNamesPromise) {
  const Problem urban = ReadShipped("urban_full.yaml");
  EXPECT_TRUE(urban.sensors.lidar && urban.sensors.wheel && urban.sensors.gnss);
  const ProblemCalibration& u = urban.calibration;
  for (BlockMode mode :
       {u.T_I_L.rotation.mode, u.T_I_L.translation.mode, u.time_offset_lidar_imu_s.mode,
        u.wheel_radius_left_m.mode, u.wheel_radius_right_m.mode, u.track_width_m.mode,
        u.p_I_A_m.mode, u.T_I_V.rotation.mode, u.T_I_V.translation.mode}) {
    EXPECT_EQ(mode, BlockMode::kEstimate);
  }

  const Problem highway = ReadShipped("highway.yaml");
  EXPECT_TRUE(highway.sensors.lidar && highway.sensors.wheel && highway.sensors.gnss);
  const ProblemCalibration& h = highway.calibration;
  EXPECT_STREQ(BlockModeName(h.T_I_L.rotation.mode), "estimate");
  EXPECT_STREQ(BlockModeName(h.T_I_L.translation.mode), "prior");
  EXPECT_EQ(h.T_I_L.translation.mode, BlockMode::kPrior);
  EXPECT_EQ(h.T_I_L.translation.prior_sigma, Eigen::Vector3d(0.05, 0.05, 0.02));
  EXPECT_EQ(h.track_width_m.mode, BlockMode::kPrior);
  EXPECT_EQ(h.track_width_m.prior_sigma, 0.03);
  EXPECT_EQ(h.p_I_A_m.mode, BlockMode::kPrior);
  EXPECT_EQ(h.p_I_A_m.prior_sigma, Eigen::Vector3d::Constant(0.05));

  const Problem lidar_imu = ReadShipped("lidar_imu.yaml");
  EXPECT_TRUE(lidar_imu.sensors.lidar);
  EXPECT_FALSE(lidar_imu.sensors.wheel);
  EXPECT_FALSE(lidar_imu.sensors.gnss);
  const ProblemCalibration& l = lidar_imu.calibration;
  EXPECT_EQ(l.T_I_L.rotation.mode, BlockMode::kEstimate);
  EXPECT_EQ(l.time_offset_lidar_imu_s.mode, BlockMode::kEstimate);
  EXPECT_TRUE(Fixed(l.wheel_radius_left_m) && Fixed(l.wheel_radius_right_m) &&
              Fixed(l.track_width_m) && Fixed(l.p_I_A_m) && Fixed(l.T_I_V.rotation) &&
              Fixed(l.T_I_V.translation));

  const Problem no_lidar = ReadShipped("imu_wheel_gnss.yaml");
  EXPECT_FALSE(no_lidar.sensors.lidar);
  EXPECT_TRUE(no_lidar.sensors.wheel && no_lidar.sensors.gnss);
  const ProblemCalibration& n = no_lidar.calibration;
  EXPECT_TRUE(Fixed(n.T_I_L.rotation) && Fixed(n.T_I_L.translation) &&
              Fixed(n.time_offset_lidar_imu_s));
  EXPECT_EQ(n.wheel_radius_left_m.mode, BlockMode::kEstimate);
  EXPECT_EQ(n.T_I_V.translation.mode, BlockMode::kPrior);
}

TEST(ProblemYamlTest, EmptyMapsGiveTheDocumentedDefaults) {
  const Problem read = ReadProblemYaml(WriteProblem("defaults.yaml", "sensors: {}\n"));
  const Problem defaults;
  EXPECT_TRUE(read.sensors.lidar && read.sensors.wheel && read.sensors.gnss);
  EXPECT_EQ(read.calibration.T_I_L.rotation.mode, BlockMode::kEstimate);
  EXPECT_FALSE(read.calibration.wheel_radius_shared);
  EXPECT_EQ(read.window_size, defaults.window_size);
  EXPECT_EQ(read.solver.max_iterations, defaults.solver.max_iterations);
  EXPECT_EQ(read.solver.outer_iterations, defaults.solver.outer_iterations);
  EXPECT_EQ(read.solver.num_threads, defaults.solver.num_threads);
  EXPECT_EQ(read.lidar.max_points_per_sweep, defaults.lidar.max_points_per_sweep);
  EXPECT_EQ(read.lidar.voxel_m, defaults.lidar.voxel_m);
  EXPECT_EQ(read.lidar.sweep_stride, 1);
  EXPECT_EQ(read.loss.gnss.type, factors::FactorLossOptions().gnss.type);
  EXPECT_EQ(read.loss.gnss.scale, factors::FactorLossOptions().gnss.scale);
  // Timing limits come from the dataset's stamps unless the file sets them.
  EXPECT_FALSE(read.timing.max_imu_gap_s || read.timing.max_wheel_gap_s ||
               read.timing.max_fix_gap_s || read.timing.keyframe_period_s ||
               read.timing.gnss_track_half_width_s);
  EXPECT_EQ(read.timing.min_factor_fraction, 0.5);
  // The wheel and GNSS clocks are held at the nominal unless the problem estimates them.
  EXPECT_EQ(read.calibration.time_offset_wheel_imu_s.mode, BlockMode::kFixed);
  EXPECT_EQ(read.calibration.time_offset_gnss_imu_s.mode, BlockMode::kFixed);
}

// The clock offsets of the wheels and the GNSS receiver: estimate or a prior in seconds, each
// only with its sensor.
TEST(ProblemYamlTest, ClockOffsetsOfWheelsAndGnssAreRead) {
  const Problem p =
      ReadProblemYaml(WriteProblem("clocks.yaml",
                                   "sensors: {lidar: false}\n"
                                   "calibration:\n"
                                   "  time_offset_wheel_imu_s: estimate\n"
                                   "  time_offset_gnss_imu_s: {prior_sigma_s: 0.05}\n"));
  EXPECT_EQ(p.calibration.time_offset_wheel_imu_s.mode, BlockMode::kEstimate);
  EXPECT_EQ(p.calibration.time_offset_gnss_imu_s.mode, BlockMode::kPrior);
  EXPECT_EQ(p.calibration.time_offset_gnss_imu_s.prior_sigma, 0.05);
  for (const auto& [sensor, key] :
       {std::pair<std::string, std::string>{"wheel", "time_offset_wheel_imu_s"},
        std::pair<std::string, std::string>{"gnss", "time_offset_gnss_imu_s"}}) {
    const std::string path =
        WriteProblem("clock_without_" + sensor + ".yaml",
                     "sensors: {" + sensor + ": false}\ncalibration:\n  " + key + ": estimate\n");
    try {
      ReadProblemYaml(path);
      ADD_FAILURE() << key << ": no error";
    } catch (const ParseError& e) {
      EXPECT_EQ(e.location().line, 3) << e.what();
      EXPECT_THAT(e.what(), ::testing::HasSubstr("sensors." + sensor + " is false")) << e.what();
    }
  }
}

TEST(ProblemYamlTest, TimingOverridesAreRead) {
  const Problem p = ReadProblemYaml(
      WriteProblem("timing.yaml",
                   "sensors: {lidar: false}\n"
                   "timing: {max_imu_gap_s: 0.1, max_wheel_gap_s: 0.3, max_fix_gap_s: 1.5,\n"
                   "         keyframe_period_s: 0.4, gnss_track_half_width_s: 4,\n"
                   "         min_factor_fraction: 0.8}\n"));
  EXPECT_EQ(p.timing.max_imu_gap_s, 0.1);
  EXPECT_EQ(p.timing.max_wheel_gap_s, 0.3);
  EXPECT_EQ(p.timing.max_fix_gap_s, 1.5);
  EXPECT_EQ(p.timing.keyframe_period_s, 0.4);
  EXPECT_EQ(p.timing.gnss_track_half_width_s, 4.0);
  EXPECT_EQ(p.timing.min_factor_fraction, 0.8);
}

TEST(ProblemYamlTest, GroundTiltSigmaIsReadOrSwitchedOff) {
  EXPECT_EQ(ReadProblemYaml(WriteProblem("tilt_default.yaml", "sensors: {lidar: false}\n"))
                .calibration.ground_tilt_sigma_deg,
            1.0);
  EXPECT_EQ(
      ReadProblemYaml(WriteProblem("tilt.yaml", "calibration: {ground_tilt_sigma_deg: 2.5}\n"))
          .calibration.ground_tilt_sigma_deg,
      2.5);
  EXPECT_FALSE(ReadProblemYaml(
                   WriteProblem("tilt_none.yaml", "calibration: {ground_tilt_sigma_deg: none}\n"))
                   .calibration.ground_tilt_sigma_deg);
}

TEST(ProblemYamlTest, RollPitchRateSigmaIsMeasuredGivenOrLeftOut) {
  const auto read = [](const char* name, const std::string& value) {
    return ReadProblemYaml(
               WriteProblem(name, "calibration: {roll_pitch_rate_sigma_rad_s: " + value + "}\n"))
        .calibration.roll_pitch_rate_sigma_rad_s;
  };
  EXPECT_FALSE(ReadProblemYaml(WriteProblem("rate_default.yaml", "sensors: {lidar: false}\n"))
                   .calibration.roll_pitch_rate_sigma_rad_s);
  EXPECT_EQ(read("rate_measured.yaml", "measured"), std::optional<double>(0.0));
  EXPECT_EQ(read("rate_given.yaml", "0.02"), std::optional<double>(0.02));
  EXPECT_FALSE(read("rate_none.yaml", "none"));
  EXPECT_THROW(read("rate_zero.yaml", "0"), ParseError);
  EXPECT_THROW(read("rate_word.yaml", "measure"), ParseError);
  EXPECT_THROW(
      ReadProblemYaml(WriteProblem(
          "rate_no_wheel.yaml",
          "sensors: {wheel: false}\ncalibration: {roll_pitch_rate_sigma_rad_s: measured}\n")),
      ParseError);
}

TEST(ProblemYamlTest, EveryKeyIsRead) {
  const std::string text =
      "description: test rig\n"
      "sensors: {imu: true, lidar: true, wheel: true, gnss: true}\n"
      "calibration:\n"
      "  T_I_L: {rotation: {prior_sigma_deg: [1, 2, 3]}, translation: fixed}\n"
      "  time_offset_lidar_imu_s: {prior_sigma_s: 0.005}\n"
      "  wheel_radius_left_m: {prior_sigma_m: 0.002}\n"
      "  wheel_radius_shared: true\n"
      "  track_width_m: fixed\n"
      "  p_I_A_m: {prior_sigma_m: 0.1}\n"
      "  T_I_V: {rotation: fixed}\n"
      "loss: {imu: \"huber:4\", prior: none, wheel: cauchy, gnss: \"huber 2.5\", lidar: none}\n"
      "window: {size: 7, max_range_m: 60}\n"
      "solver: {max_iterations: 30, outer_iterations: 3, num_threads: 2}\n"
      "lidar: {max_points_per_sweep: 800, voxel_m: 0.25, sweep_stride: 3}\n";
  const Problem p = ReadProblemYaml(WriteProblem("full.yaml", text));
  EXPECT_EQ(p.description, "test rig");
  const ProblemCalibration& c = p.calibration;
  EXPECT_EQ(c.T_I_L.rotation.mode, BlockMode::kPrior);
  EXPECT_EQ(c.T_I_L.rotation.prior_sigma, Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(c.T_I_L.translation.mode, BlockMode::kFixed);
  EXPECT_EQ(c.time_offset_lidar_imu_s.mode, BlockMode::kPrior);
  EXPECT_EQ(c.time_offset_lidar_imu_s.prior_sigma, 0.005);
  // Shared radii: the left setting applies to both wheels.
  EXPECT_TRUE(c.wheel_radius_shared);
  EXPECT_EQ(c.wheel_radius_right_m.mode, BlockMode::kPrior);
  EXPECT_EQ(c.wheel_radius_right_m.prior_sigma, 0.002);
  EXPECT_EQ(c.track_width_m.mode, BlockMode::kFixed);
  EXPECT_EQ(c.p_I_A_m.prior_sigma, Eigen::Vector3d::Constant(0.1));
  EXPECT_EQ(c.T_I_V.rotation.mode, BlockMode::kFixed);
  EXPECT_EQ(c.T_I_V.translation.mode, BlockMode::kEstimate);
  EXPECT_EQ(p.loss.imu.type, factors::RobustLoss::kHuber);
  EXPECT_EQ(p.loss.imu.scale, 4.0);
  EXPECT_EQ(p.loss.wheel.type, factors::RobustLoss::kCauchy);
  EXPECT_EQ(p.loss.wheel.scale, 1.0);
  EXPECT_EQ(p.loss.gnss.type, factors::RobustLoss::kHuber);
  EXPECT_EQ(p.loss.gnss.scale, 2.5);
  EXPECT_EQ(p.loss.lidar.type, factors::RobustLoss::kNone);
  EXPECT_EQ(p.window_size, 7);
  EXPECT_EQ(p.window_max_range_m, 60.0);
  EXPECT_EQ(p.solver.max_iterations, 30);
  EXPECT_EQ(p.solver.outer_iterations, 3);
  EXPECT_EQ(p.solver.num_threads, 2);
  EXPECT_EQ(p.lidar.max_points_per_sweep, 800);
  EXPECT_EQ(p.lidar.voxel_m, 0.25);
  EXPECT_EQ(p.lidar.sweep_stride, 3);
}

// The blocks of the wheel forms linear_speeds and speed_yaw_rate: read like the others,
// estimated by default, fixed without the wheels, their sigmas checked with their place.
TEST(ProblemYamlTest, WheelFormBlocksAreRead) {
  const std::string text =
      "calibration:\n"
      "  wheel_speed_scale_left: {prior_sigma: 0.01}\n"
      "  wheel_speed_scale_right: fixed\n"
      "  odometry_speed_scale: {prior_sigma: 0.05}\n"
      "  effective_track_m: {prior_sigma_m: 0.3}\n";
  const ProblemCalibration c = ReadProblemYaml(WriteProblem("forms.yaml", text)).calibration;
  EXPECT_EQ(c.wheel_speed_scale_left.mode, BlockMode::kPrior);
  EXPECT_EQ(c.wheel_speed_scale_left.prior_sigma, 0.01);
  EXPECT_EQ(c.wheel_speed_scale_right.mode, BlockMode::kFixed);
  EXPECT_EQ(c.odometry_speed_scale.prior_sigma, 0.05);
  EXPECT_EQ(c.effective_track_m.mode, BlockMode::kPrior);
  EXPECT_EQ(c.effective_track_m.prior_sigma, 0.3);
  const ProblemCalibration defaults =
      ReadProblemYaml(WriteProblem("forms_default.yaml", "sensors: {}\n")).calibration;
  EXPECT_EQ(defaults.odometry_speed_scale.mode, BlockMode::kEstimate);
  EXPECT_EQ(defaults.effective_track_m.mode, BlockMode::kEstimate);
  const ProblemCalibration no_wheel =
      ReadProblemYaml(WriteProblem("forms_no_wheel.yaml", "sensors: {wheel: false}\n")).calibration;
  EXPECT_EQ(no_wheel.odometry_speed_scale.mode, BlockMode::kFixed);
  EXPECT_EQ(no_wheel.wheel_speed_scale_left.mode, BlockMode::kFixed);
  // A scale's sigma has no unit: 1.0 (100 %) at most.
  try {
    ReadProblemYaml(WriteProblem("forms_sigma.yaml",
                                 "calibration:\n  odometry_speed_scale: {prior_sigma: 5}\n"));
    ADD_FAILURE() << "a scale sigma of 5 was accepted";
  } catch (const ParseError& e) {
    EXPECT_EQ(e.location().line, 2);
    EXPECT_EQ(e.location().column, 39);
    EXPECT_THAT(e.detail(), HasSubstr("calibration.odometry_speed_scale.prior_sigma: must be "
                                      "within [1e-06, 1]"));
  }
  try {
    ReadProblemYaml(WriteProblem("forms_without_wheel.yaml",
                                 "sensors: {wheel: false}\ncalibration:\n"
                                 "  effective_track_m: estimate\n"));
    ADD_FAILURE() << "effective_track_m accepted without the wheels";
  } catch (const ParseError& e) {
    EXPECT_EQ(e.location().line, 3);
    EXPECT_THAT(e.detail(), HasSubstr("sensors.wheel is false"));
  }
}

TEST(ProblemYamlTest, BadInputsNameLineAndColumn) {
  const std::vector<BadCase> cases = {
      {"unknown_top", "sensors: {}\nwindows: {size: 5}\n", 2, "windows", "unknown key 'windows'"},
      {"unknown_block", "calibration:\n  track_widht_m: estimate\n", 2, "track_widht_m",
       "calibration: unknown key 'track_widht_m'"},
      {"unknown_pose_part", "calibration:\n  T_I_L: {rotation: estimate, rot: fixed}\n", 2,
       "rot:", "calibration.T_I_L: unknown key 'rot'"},
      {"bad_mode", "calibration:\n  T_I_L:\n    rotation: estimated\n", 3, "estimated",
       "calibration.T_I_L.rotation: expected estimate, fixed or {prior_sigma_deg: "},
      {"prior_without_sigma", "calibration:\n  track_width_m: prior\n", 2, "prior",
       "expected estimate, fixed or {prior_sigma_m: sigma}, found 'prior'"},
      {"wrong_sigma_unit", "calibration:\n  time_offset_lidar_imu_s: {prior_sigma_m: 0.01}\n", 2,
       "prior_sigma_m", "unknown key 'prior_sigma_m' (expected one of: prior_sigma_s)"},
      {"negative_sigma", "calibration:\n  track_width_m: {prior_sigma_m: -0.1}\n", 2, "-0.1",
       "prior_sigma_m: must be within [1e-06, 100] m, found -0.1"},
      {"zero_axis_sigma", "calibration:\n  p_I_A_m: {prior_sigma_m: [0.1, 0, 0.1]}\n", 2, "0,",
       "calibration.p_I_A_m.prior_sigma_m[1]: must be within [1e-06, 100] m, found 0"},
      {"short_sigma", "calibration:\n  p_I_A_m: {prior_sigma_m: [0.1, 0.1]}\n", 2, "[",
       "expected a list of 3 numbers"},
      {"sensor_not_bool", "sensors:\n  wheel: yes\n", 2, "yes",
       "sensors.wheel: expected true or false"},
      {"imu_off", "sensors:\n  imu: false\n", 2, "false", "the IMU always takes part"},
      {"nothing_but_imu", "sensors:\n  lidar: false\n  wheel: false\n  gnss: false\n", 2, "lidar",
       "the IMU alone calibrates nothing"},
      {"block_of_absent_sensor",
       "sensors: {wheel: false}\ncalibration:\n  T_I_L: {rotation: estimate}\n  track_width_m: "
       "estimate\n",
       4, "track_width_m", "calibration.track_width_m: sensors.wheel is false"},
      {"loss_of_absent_sensor", "sensors: {gnss: false}\nloss:\n  gnss: \"cauchy:3\"\n", 3, "gnss",
       "loss.gnss: sensors.gnss is false"},
      {"lidar_section_without_lidar", "sensors: {lidar: false}\nlidar: {voxel_m: 0.5}\n", 2,
       "lidar", "lidar: sensors.lidar is false, so this setting has no effect"},
      {"bad_loss", "loss:\n  wheel: \"hubber:2\"\n", 2, "\"hubber",
       "loss.wheel: unknown robust loss 'hubber'"},
      {"bad_loss_scale", "loss:\n  lidar: \"huber:-1\"\n", 2, "\"huber",
       "loss.lidar: robust loss 'huber:-1': scale must be between 0.001 and 1000 sigmas, got -1"},
      {"loss_not_scalar", "loss:\n  lidar: [huber, 1]\n", 2, "[", "loss.lidar: expected a scalar"},
      {"window_too_small", "window: {size: 1}\n", 1, "1", "window.size: must be within [2, 10000]"},
      {"window_not_int", "window:\n  size: 10.5\n", 2, "10.5", "window.size"},
      {"threads_zero", "solver:\n  num_threads: 0\n", 2, "0", "solver.num_threads: must be within"},
      {"voxel_zero", "lidar:\n  voxel_m: 0\n", 2, "0",
       "lidar.voxel_m: must be within [0.01, 20] m, found 0"},
      {"negative_range", "window:\n  max_range_m: -5\n", 2, "-5",
       "window.max_range_m: must be 0 (no limit) or within [1, 10000] m, found -5"},
      {"range_without_lidar", "sensors: {lidar: false}\nwindow: {max_range_m: 30}\n", 2,
       "max_range_m", "window.max_range_m: sensors.lidar is false"},
      {"stride_zero", "lidar:\n  sweep_stride: 0\n", 2, "0",
       "lidar.sweep_stride: must be within [1, 100]"},
      {"shared_mismatch",
       "calibration:\n  wheel_radius_shared: true\n  wheel_radius_left_m: estimate\n"
       "  wheel_radius_right_m: fixed\n",
       4, "fixed", "wheel_radius_shared is true, so both radii are one parameter"},
      {"not_a_map", "- sensors\n", 1, "-", "problem: expected a map"},
      {"unknown_timing", "timing:\n  max_gap_s: 1\n", 2, "max_gap_s",
       "timing: unknown key 'max_gap_s'"},
      {"gap_zero", "timing:\n  max_wheel_gap_s: 0\n", 2, "0",
       "timing.max_wheel_gap_s: must be within [0.001, 60] s, found 0"},
      {"gap_nan", "timing:\n  max_fix_gap_s: .nan\n", 2, ".nan", "timing.max_fix_gap_s"},
      {"period_huge", "sensors: {lidar: false}\ntiming: {keyframe_period_s: 1e9}\n", 2, "1e9",
       "timing.keyframe_period_s: must be within [0.005, 10] s, found 1e9"},
      {"period_with_lidar", "timing:\n  keyframe_period_s: 0.2\n", 2, "keyframe_period_s",
       "timing.keyframe_period_s: sensors.lidar is true, so the keyframes are the LiDAR sweeps"},
      {"fix_gap_without_gnss", "sensors: {gnss: false}\ntiming:\n  max_fix_gap_s: 1\n", 3,
       "max_fix_gap_s", "timing.max_fix_gap_s: sensors.gnss is false"},
      {"tilt_zero", "calibration:\n  ground_tilt_sigma_deg: 0\n", 2, "0",
       "calibration.ground_tilt_sigma_deg: must be within [0.01, 30] deg (or none), found 0"},
      {"tilt_without_wheel", "sensors: {wheel: false}\ncalibration:\n  ground_tilt_sigma_deg: 1\n",
       3, "ground_tilt_sigma_deg", "calibration.ground_tilt_sigma_deg: sensors.wheel is false"},
      {"fraction_above_one", "timing:\n  min_factor_fraction: 1.5\n", 2, "1.5",
       "timing.min_factor_fraction: must be within [0, 1] (a fraction of the keyframes), found "
       "1.5"},
  };
  for (const BadCase& c : cases) ExpectParseError(c);
}

// Settings outside their physical range (zero, negative, subnormal, absurd, non-finite) are
// refused where they stand: a 1e-300 m voxel overflowed the voxel index, a 1e308 m one left
// one residual point per sweep, a 1e-300 sigma has an infinite information.
TEST(ProblemYamlTest, RefusesSettingsOutsideTheirPhysicalRange) {
  const std::vector<BadCase> cases = {
      {"voxel_tiny", "lidar:\n  voxel_m: 1e-300\n", 2, "1e-300",
       "lidar.voxel_m: must be within [0.01, 20] m, found 1e-300"},
      {"voxel_huge", "lidar:\n  voxel_m: 1e308\n", 2, "1e308",
       "lidar.voxel_m: must be within [0.01, 20] m, found 1e308"},
      {"voxel_nan", "lidar:\n  voxel_m: .nan\n", 2, ".nan", "lidar.voxel_m"},
      {"voxel_inf", "lidar:\n  voxel_m: .inf\n", 2, ".inf", "lidar.voxel_m"},
      {"range_tiny", "window:\n  max_range_m: 1e-300\n", 2, "1e-300",
       "window.max_range_m: must be 0 (no limit) or within [1, 10000] m"},
      {"range_huge", "window:\n  max_range_m: 1e300\n", 2, "1e300", "window.max_range_m"},
      {"sigma_tiny", "calibration:\n  time_offset_lidar_imu_s: {prior_sigma_s: 1e-300}\n", 2,
       "1e-300", "time_offset_lidar_imu_s.prior_sigma_s: must be within [1e-09, 10] s"},
      {"sigma_deg_huge", "calibration:\n  T_I_V: {rotation: {prior_sigma_deg: 1e300}}\n", 2,
       "1e300", "T_I_V.rotation.prior_sigma_deg: must be within [1e-06, 180] deg"},
      {"sigma_axis_huge", "calibration:\n  p_I_A_m: {prior_sigma_m: [0.1, 0.1, 1e9]}\n", 2, "1e9",
       "p_I_A_m.prior_sigma_m[2]: must be within [1e-06, 100] m, found 1e9"},
  };
  for (const BadCase& c : cases) ExpectParseError(c);
  // The ends of each range are accepted.
  const Problem edges =
      ReadProblemYaml(WriteProblem("range_edges.yaml",
                                   "calibration:\n  time_offset_lidar_imu_s: {prior_sigma_s: 10}\n"
                                   "  T_I_V: {rotation: {prior_sigma_deg: 1e-6}}\n"
                                   "window: {max_range_m: 0}\nlidar: {voxel_m: 0.01}\n"));
  EXPECT_EQ(edges.lidar.voxel_m, 0.01);
  EXPECT_EQ(edges.window_max_range_m, 0.0);
}

Dataset DatasetWith(bool imu, bool lidar, bool wheel, bool gnss) {
  Dataset dataset;
  dataset.directory = "/nonexistent/run3";
  if (imu) dataset.imu.resize(10);
  if (lidar) dataset.lidar_sweeps.resize(3);
  if (wheel) dataset.wheel.resize(5);
  if (gnss) dataset.gnss.resize(5);
  return dataset;
}

std::string ValidationMessage(const Problem& problem, const Dataset& dataset) {
  try {
    ValidateProblemForDataset(problem, dataset);
  } catch (const ParseError& e) {
    ADD_FAILURE() << "validation must not be a ParseError: " << e.what();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(ProblemYamlTest, ValidationAcceptsADatasetWithEverythingTheProblemUses) {
  EXPECT_NO_THROW(ValidateProblemForDataset(ReadShipped("urban_full.yaml"),
                                            DatasetWith(true, true, true, true)));
  // The LiDAR-IMU problem needs neither wheels nor GNSS.
  EXPECT_NO_THROW(ValidateProblemForDataset(ReadShipped("lidar_imu.yaml"),
                                            DatasetWith(true, true, false, false)));
  EXPECT_NO_THROW(ValidateProblemForDataset(ReadShipped("imu_wheel_gnss.yaml"),
                                            DatasetWith(true, false, true, true)));
}

TEST(ProblemYamlTest, ValidationRefusesWhatTheDatasetCannotGive) {
  const Problem urban = ReadShipped("urban_full.yaml");
  EXPECT_EQ(ValidationMessage(urban, DatasetWith(true, true, false, true)),
            "problem " + urban.path +
                " estimates wheel_radius_left_m but dataset /nonexistent/run3 has no wheel.csv");
  EXPECT_EQ(ValidationMessage(urban, DatasetWith(true, false, true, true)),
            "problem " + urban.path +
                " estimates T_I_L rotation but dataset /nonexistent/run3 has no lidar.csv");
  EXPECT_EQ(
      ValidationMessage(urban, DatasetWith(true, true, true, false)),
      "problem " + urban.path + " estimates p_I_A_m but dataset /nonexistent/run3 has no gnss.csv");
  // Every missing piece in one message.
  const std::string all = ValidationMessage(urban, DatasetWith(false, false, false, false));
  EXPECT_THAT(all, HasSubstr("has 0 IMU samples in imu.csv"));
  EXPECT_THAT(all, HasSubstr("no lidar.csv"));
  EXPECT_THAT(all, HasSubstr("no wheel.csv"));
  EXPECT_THAT(all, HasSubstr("no gnss.csv"));

  // The verb follows the block's mode; the first block that is not fixed is named.
  Problem problem;
  problem.path = "problems/x.yaml";
  problem.calibration.T_I_L.rotation.mode = BlockMode::kFixed;
  problem.calibration.T_I_L.translation.mode = BlockMode::kFixed;
  problem.calibration.time_offset_lidar_imu_s = {BlockMode::kPrior, 0.01};
  EXPECT_EQ(ValidationMessage(problem, DatasetWith(true, false, true, true)),
            "problem problems/x.yaml puts a prior on time_offset_lidar_imu_s but dataset "
            "/nonexistent/run3 has no lidar.csv");
  // A sensor whose blocks are all fixed still needs its data (its factors remain).
  problem.calibration.p_I_A_m.mode = BlockMode::kFixed;
  EXPECT_EQ(ValidationMessage(problem, DatasetWith(true, true, true, false)),
            "problem problems/x.yaml uses GNSS but dataset /nonexistent/run3 has no gnss.csv");
}

// The dataset's wheel form decides which file the wheels need and which blocks the message
// names.
TEST(ProblemYamlTest, ValidationFollowsTheWheelForm) {
  const Problem urban = ReadShipped("urban_full.yaml");
  Dataset twist = DatasetWith(true, true, false, true);
  twist.sensors.wheel = sensors::WheelConfig();
  twist.sensors.wheel->form = sensors::WheelForm::kSpeedYawRate;
  EXPECT_EQ(ValidationMessage(urban, twist),
            "problem " + urban.path +
                " estimates odometry_speed_scale but dataset /nonexistent/run3 has no "
                "odometry.csv");
  // With its file, every form is accepted (the calibration takes each).
  twist.odometry.resize(4);
  EXPECT_EQ(ValidationMessage(urban, twist), "");
  Dataset speeds = DatasetWith(true, true, false, true);
  speeds.sensors.wheel = sensors::WheelConfig();
  speeds.sensors.wheel->form = sensors::WheelForm::kLinearSpeeds;
  EXPECT_THAT(ValidationMessage(urban, speeds),
              HasSubstr("estimates wheel_speed_scale_left but dataset /nonexistent/run3 has no "
                        "wheel_speed.csv"));
  Problem scales = urban;
  scales.calibration.wheel_speed_scale_left = {BlockMode::kPrior, 0.01};
  EXPECT_THAT(ValidationMessage(scales, speeds),
              HasSubstr("puts a prior on wheel_speed_scale_left but"));
  speeds.wheel_speeds.resize(4);
  EXPECT_EQ(ValidationMessage(scales, speeds), "");
}

// Stamps of one sensor that never meet the IMU's (microseconds, another clock) would give
// the solve no factor of that sensor: refused before any work, naming file and spans.
TEST(ProblemYamlTest, ValidationRefusesSamplesOutsideTheImuTimeSpan) {
  const Problem urban = ReadShipped("urban_full.yaml");
  Dataset dataset = DatasetWith(true, true, true, true);
  const int64_t t0_ns = 1'700'000'000'000'000'000;
  for (size_t i = 0; i < dataset.imu.size(); ++i) {
    dataset.imu[i].t_ns = t0_ns + static_cast<int64_t>(i) * 5'000'000;
  }
  for (size_t i = 0; i < dataset.lidar_sweeps.size(); ++i) {
    dataset.lidar_sweeps[i].t_ns = t0_ns + static_cast<int64_t>(i) * 10'000'000;
  }
  for (size_t i = 0; i < dataset.gnss.size(); ++i) {
    dataset.gnss[i].t_ns = t0_ns + static_cast<int64_t>(i) * 10'000'000;
  }
  // The wheels stamped in microseconds.
  for (size_t i = 0; i < dataset.wheel.size(); ++i) {
    dataset.wheel[i].t_ns = (t0_ns + static_cast<int64_t>(i) * 10'000'000) / 1000;
  }
  const std::string message = ValidationMessage(urban, dataset);
  EXPECT_THAT(message, HasSubstr("uses the wheel encoders but 0 of 5 samples of "
                                 "/nonexistent/run3/wheel.csv fall inside the IMU's time span"));
  EXPECT_THAT(message, HasSubstr("the stamps look like microseconds"));
  EXPECT_THAT(message, ::testing::Not(HasSubstr("gnss.csv")));
  EXPECT_THAT(message, ::testing::Not(HasSubstr("lidar.csv")));
  // GNSS an hour late: another clock.
  for (size_t i = 0; i < dataset.wheel.size(); ++i) dataset.wheel[i].t_ns = dataset.gnss[i].t_ns;
  for (sensors::GnssFix& fix : dataset.gnss) fix.t_ns += int64_t{3600} * 1'000'000'000;
  EXPECT_THAT(ValidationMessage(urban, dataset),
              HasSubstr("uses GNSS but 0 of 5 samples of /nonexistent/run3/gnss.csv fall inside "
                        "the IMU's time span"));
  // Within the span, or a LiDAR clock a few milliseconds off, is accepted.
  for (sensors::GnssFix& fix : dataset.gnss) fix.t_ns -= int64_t{3600} * 1'000'000'000;
  for (LidarSweepRef& sweep : dataset.lidar_sweeps) sweep.t_ns -= 200'000'000;
  EXPECT_EQ(ValidationMessage(urban, dataset), "");
}

TEST(ProblemYamlTest, ValidationTellsAnEmptyFileFromAMissingOne) {
  const std::filesystem::path dir = test::OutputDir("empty_wheel");
  std::ofstream(dir / "wheel.csv") << "t_ns,left_rad_s,right_rad_s\n";
  Dataset dataset = DatasetWith(true, true, false, true);
  dataset.directory = dir.string();
  EXPECT_THAT(ValidationMessage(ReadShipped("urban_full.yaml"), dataset),
              HasSubstr("has no samples in wheel.csv"));
}

}  // namespace
}  // namespace io
}  // namespace autocal
