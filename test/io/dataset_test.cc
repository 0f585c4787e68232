#include "autocal/io/dataset.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/io/csv_files.h"
#include "autocal/io/sensors_yaml.h"
#include "io/io_test_data.h"
#include "support/test_paths.h"

namespace autocal {
namespace io {
namespace {

using ::testing::HasSubstr;
namespace fs = std::filesystem;

// A fresh dataset directory written by DatasetWriter from the reference drive.
std::string WriteDrive(const std::string& name, const test_data::Drive& drive) {
  const fs::path directory = test::OutputDir("dataset") / name;
  fs::remove_all(directory);
  DatasetWriter writer(directory.string());
  writer.WriteSensorsConfig(drive.config);
  writer.WriteImu(drive.imu);
  writer.WriteWheel(drive.wheel);
  writer.WriteGnss(drive.gnss);
  for (const lidar::LidarSweep& sweep : drive.sweeps) writer.AddSweep(sweep);
  writer.WriteGroundTruth(drive.trajectory, drive.calibration);
  writer.Close();
  return directory.string();
}

TEST(DatasetTest, WriterAndReaderRoundTripExactly) {
  const test_data::Drive drive = test_data::MakeDrive(2.0);
  const std::string directory = WriteDrive("round_trip", drive);
  const Dataset dataset = ReadDataset(directory);
  EXPECT_EQ(dataset.directory, directory);

  ASSERT_EQ(dataset.imu.size(), drive.imu.size());
  for (size_t i = 0; i < drive.imu.size(); ++i) {
    ASSERT_EQ(dataset.imu[i].t_ns, drive.imu[i].t_ns) << "imu " << i;
    ASSERT_EQ(dataset.imu[i].gyro_rad_s, drive.imu[i].gyro_rad_s) << "imu " << i;
    ASSERT_EQ(dataset.imu[i].accel_m_s2, drive.imu[i].accel_m_s2) << "imu " << i;
  }
  ASSERT_EQ(dataset.wheel.size(), drive.wheel.size());
  for (size_t i = 0; i < drive.wheel.size(); ++i) {
    ASSERT_EQ(dataset.wheel[i].left_rad_s, drive.wheel[i].left_rad_s) << "wheel " << i;
    ASSERT_EQ(dataset.wheel[i].right_rad_s, drive.wheel[i].right_rad_s) << "wheel " << i;
  }
  ASSERT_EQ(dataset.gnss.size(), drive.gnss.size());
  for (size_t i = 0; i < drive.gnss.size(); ++i) {
    ASSERT_EQ(dataset.gnss[i].lat_deg, drive.gnss[i].lat_deg) << "gnss " << i;
    ASSERT_EQ(dataset.gnss[i].lon_deg, drive.gnss[i].lon_deg) << "gnss " << i;
  }
  ASSERT_EQ(dataset.groundtruth_trajectory.size(), drive.trajectory.size());
  for (size_t i = 0; i < drive.trajectory.size(); ++i) {
    const TrajectorySample& a = dataset.groundtruth_trajectory[i];
    const TrajectorySample& b = drive.trajectory[i];
    ASSERT_EQ(a.t_ns, b.t_ns) << "pose " << i;
    ASSERT_EQ(a.T_W_I.p, b.T_W_I.p) << "pose " << i;
    ASSERT_EQ(a.T_W_I.q.coeffs(), b.T_W_I.q.coeffs()) << "pose " << i;
    ASSERT_EQ(a.v_W_I, b.v_W_I) << "pose " << i;
  }
  ASSERT_TRUE(dataset.groundtruth_calibration.has_value());
  EXPECT_EQ(dataset.groundtruth_calibration->p_I_L, drive.calibration.p_I_L);
  EXPECT_EQ(dataset.groundtruth_calibration->q_I_L.coeffs(), drive.calibration.q_I_L.coeffs());
  EXPECT_EQ(dataset.groundtruth_calibration->time_offset_lidar_imu_s,
            drive.calibration.time_offset_lidar_imu_s);
  EXPECT_EQ(dataset.sensors.nominal_calibration.p_I_L, drive.config.nominal_calibration.p_I_L);
  EXPECT_TRUE(dataset.sensors.lidar && dataset.sensors.wheel && dataset.sensors.gnss);

  ASSERT_EQ(dataset.lidar_sweeps.size(), drive.sweeps.size());
  for (size_t i = 0; i < drive.sweeps.size(); ++i) {
    ASSERT_EQ(dataset.lidar_sweeps[i].t_ns, drive.sweeps[i].t_ns) << "sweep " << i;
    const lidar::LidarSweep sweep = dataset.LoadSweep(i);
    ASSERT_EQ(sweep.t_ns, drive.sweeps[i].t_ns);
    ASSERT_EQ(sweep.cloud.points, drive.sweeps[i].cloud.points) << "sweep " << i;
    ASSERT_EQ(sweep.cloud.intensity, drive.sweeps[i].cloud.intensity) << "sweep " << i;
    ASSERT_EQ(sweep.cloud.time_s, drive.sweeps[i].cloud.time_s) << "sweep " << i;
  }
  EXPECT_THROW(dataset.LoadSweep(drive.sweeps.size()), Error);
}

// DatasetUntil keeps every stream's samples stamped at or before the end, the sweeps' files
// still readable, and the configuration and ground-truth calibration as they are.
TEST(DatasetTest, DatasetUntilKeepsWhatIsStampedUpToTheEnd) {
  const test_data::Drive drive = test_data::MakeDrive(2.0);
  Dataset dataset = ReadDataset(WriteDrive("until", drive));
  ASSERT_GE(dataset.lidar_sweeps.size(), 3u);
  // The other wheel forms' series, at the encoders' stamps (only the stamps matter here).
  for (const sensors::WheelSample& w : dataset.wheel) {
    dataset.wheel_speeds.emplace_back();
    dataset.wheel_speeds.back().t_ns = w.t_ns;
    dataset.odometry.emplace_back();
    dataset.odometry.back().t_ns = w.t_ns;
  }
  const int64_t end_ns = dataset.lidar_sweeps[1].t_ns;
  const Dataset first = DatasetUntil(dataset, end_ns);
  const auto expect_prefix = [end_ns](const auto& part, const auto& whole, const char* stream) {
    size_t kept = 0;
    while (kept < whole.size() && whole[kept].t_ns <= end_ns) ++kept;
    EXPECT_GT(kept, 0u) << stream;
    EXPECT_LT(kept, whole.size()) << stream;
    ASSERT_EQ(part.size(), kept) << stream;
    for (size_t i = 0; i < kept; ++i) EXPECT_EQ(part[i].t_ns, whole[i].t_ns) << stream << " " << i;
  };
  expect_prefix(first.imu, dataset.imu, "imu");
  expect_prefix(first.wheel, dataset.wheel, "wheel");
  expect_prefix(first.wheel_speeds, dataset.wheel_speeds, "wheel speeds");
  expect_prefix(first.odometry, dataset.odometry, "odometry");
  expect_prefix(first.gnss, dataset.gnss, "gnss");
  expect_prefix(first.lidar_sweeps, dataset.lidar_sweeps, "sweeps");
  expect_prefix(first.groundtruth_trajectory, dataset.groundtruth_trajectory, "ground truth");
  EXPECT_EQ(first.lidar_sweeps.back().t_ns, end_ns);
  EXPECT_EQ(first.LoadSweep(1).cloud.points, dataset.LoadSweep(1).cloud.points);
  EXPECT_EQ(first.directory, dataset.directory);
  EXPECT_EQ(first.sensors.nominal_calibration.p_I_L, dataset.sensors.nominal_calibration.p_I_L);
  ASSERT_TRUE(first.groundtruth_calibration.has_value());
  EXPECT_TRUE(DatasetUntil(dataset, dataset.imu.front().t_ns - 1).imu.empty());
}

// The file contents are the ground truth of the analytic drive: the IMU a reader returns
// integrates back to the trajectory the same reader returns (a check that the columns mean
// what the format says: gyro in I, specific force with gravity, velocity in W).
TEST(DatasetTest, ImuAgreesWithGroundTruth) {
  const std::string directory = WriteDrive("consistency", test_data::MakeDrive(2.0));
  const Dataset dataset = ReadDataset(directory);
  const Trajectory& truth = dataset.groundtruth_trajectory;
  const Eigen::Vector3d g_W(0.0, 0.0, -dataset.sensors.imu.gravity_m_s2);
  Eigen::Quaterniond q = truth.front().T_W_I.q;
  Eigen::Vector3d v = truth.front().v_W_I;
  Eigen::Vector3d p = truth.front().T_W_I.p;
  for (size_t i = 0; i + 1 < dataset.imu.size(); ++i) {
    // Midpoint integration of the two samples around the step.
    const double dt = SecondsBetween(dataset.imu[i].t_ns, dataset.imu[i + 1].t_ns);
    const Eigen::Vector3d omega = 0.5 * (dataset.imu[i].gyro_rad_s + dataset.imu[i + 1].gyro_rad_s);
    const Eigen::Quaterniond q_next =
        q * Eigen::Quaterniond(Eigen::AngleAxisd(omega.norm() * dt, omega.normalized()));
    const Eigen::Vector3d a_W =
        0.5 * (q * dataset.imu[i].accel_m_s2 + q_next * dataset.imu[i + 1].accel_m_s2) + g_W;
    p += v * dt + 0.5 * a_W * dt * dt;
    v += a_W * dt;
    q = q_next;
  }
  const TrajectorySample& last = truth.back();
  ASSERT_EQ(last.t_ns, dataset.imu.back().t_ns);
  EXPECT_LT((p - last.T_W_I.p).norm(), 1e-3) << p.transpose() << " vs " << last.T_W_I.p.transpose();
  EXPECT_LT((v - last.v_W_I).norm(), 1e-3) << v.transpose() << " vs " << last.v_W_I.transpose();
  EXPECT_LT(q.angularDistance(last.T_W_I.q), 1e-9);
}

TEST(DatasetTest, MissingImuCsv) {
  const std::string directory = WriteDrive("no_imu", test_data::MakeDrive(0.5));
  fs::remove(fs::path(directory) / "imu.csv");
  try {
    ReadDataset(directory);
    FAIL() << "no error for a dataset without imu.csv";
  } catch (const ParseError& e) {
    EXPECT_EQ(e.location().file, (fs::path(directory) / "imu.csv").string());
    EXPECT_EQ(e.location().line, 0);
    EXPECT_THAT(e.detail(), HasSubstr("every dataset needs imu.csv"));
  }
}

TEST(DatasetTest, MissingSweepFile) {
  const test_data::Drive drive = test_data::MakeDrive(0.5);
  const std::string directory = WriteDrive("no_sweep", drive);
  const std::string missing = std::to_string(drive.sweeps[3].t_ns) + ".ply";
  fs::remove(fs::path(directory) / "lidar" / missing);
  try {
    ReadDataset(directory);
    FAIL() << "no error for a missing sweep";
  } catch (const ParseError& e) {
    EXPECT_EQ(e.location().file, (fs::path(directory) / "lidar.csv").string());
    EXPECT_EQ(e.location().line, 5);  // header + 4th sweep
    EXPECT_EQ(e.location().column,
              static_cast<int64_t>(std::to_string(drive.sweeps[3].t_ns).size()) + 2);
    EXPECT_THAT(e.detail(), HasSubstr("sweep file '" + missing + "' not found"));
  }
}

TEST(DatasetTest, OnlyImuIsRequired) {
  const fs::path directory = test::OutputDir("dataset") / "imu_only";
  fs::remove_all(directory);
  fs::create_directories(directory);
  const test_data::Drive drive = test_data::MakeDrive(0.5);
  WriteImuCsv((directory / "imu.csv").string(), drive.imu);
  const Dataset dataset = ReadDataset(directory.string());
  EXPECT_EQ(dataset.imu.size(), drive.imu.size());
  EXPECT_TRUE(dataset.wheel.empty() && dataset.gnss.empty() && dataset.lidar_sweeps.empty());
  EXPECT_FALSE(dataset.groundtruth_calibration.has_value());
  EXPECT_FALSE(dataset.sensors.lidar.has_value());
}

// sensors.yaml's optional sections may be left out (the calibration then uses the defaults of
// sensors/sensor_config.h): the reader leaves them empty.
TEST(DatasetTest, SensorsYamlWithoutOptionalSections) {
  const fs::path directory = test::OutputDir("dataset") / "no_wheel_section";
  fs::remove_all(directory);
  fs::create_directories(directory);
  std::ofstream(directory / "sensors.yaml")
      << "imu:\n  gyroscope_noise_density: 1.6968e-4\n  gyroscope_random_walk: 1.9393e-5\n"
         "  accelerometer_noise_density: 2.0e-3\n  accelerometer_random_walk: 3.0e-3\n"
         "  update_rate: 200\n";
  WriteImuCsv((directory / "imu.csv").string(), test_data::MakeDrive(0.5).imu);
  const Dataset dataset = ReadDataset(directory.string());
  EXPECT_FALSE(dataset.sensors.wheel.has_value());
  EXPECT_FALSE(dataset.sensors.gnss.has_value());
  EXPECT_FALSE(dataset.sensors.lidar.has_value());
}

// Numbers of sensors.yaml outside a physical range (a unit slip, a typo, values whose
// information overflows) are refused with file, line and column.
TEST(DatasetTest, SensorsYamlRefusesNumbersOutsideTheirRange) {
  const std::string imu =
      "imu:\n  gyroscope_noise_density: 1.6968e-4\n  gyroscope_random_walk: 1.9393e-5\n"
      "  accelerometer_noise_density: 2.0e-3\n  accelerometer_random_walk: 3.0e-3\n"
      "  update_rate: 200\n";
  struct Case {
    std::string name;
    std::string text;
    int64_t line;
    std::string value;  // the error points at it
    std::string message;
  };
  const std::vector<Case> cases = {
      {"noise_tiny",
       imu.substr(0, imu.find("1.6968e-4")) + "1e-300" + imu.substr(imu.find("1.6968e-4") + 9), 2,
       "1e-300", "imu.gyroscope_noise_density: must be within [1e-07, 1] rad/s/sqrt(Hz)"},
      {"rate_huge", imu.substr(0, imu.find("200")) + "1e308\n", 6, "1e308",
       "imu.update_rate: must be within [1, 1e+05] Hz, found 1e308"},
      {"wheel_noise_zero", imu + "wheel:\n  noise_rad_s: 0\n", 8, "0",
       "wheel.noise_rad_s: must be within [1e-06, 100] rad/s, found 0"},
      {"wheel_rate_negative", imu + "wheel:\n  rate_hz: -100\n", 8, "-100",
       "wheel.rate_hz: must be within"},
      {"gnss_rate_huge", imu + "gnss:\n  rate_hz: 1e9\n", 8, "1e9", "gnss.rate_hz: must be within"},
      {"lidar_noise_negative", imu + "lidar:\n  range_noise_m: -0.1\n", 8, "-0.1",
       "lidar.range_noise_m: must be within [0, 10] m"},
      {"lidar_range_huge", imu + "lidar:\n  max_range_m: 1e300\n", 8, "1e300",
       "lidar.max_range_m: must be within"},
      {"lidar_resolution_tiny", imu + "lidar:\n  azimuth_resolution_deg: 1e-300\n", 8, "1e-300",
       "lidar.azimuth_resolution_deg: must be within"},
      {"noise_nan", imu + "wheel:\n  noise_rad_s: .nan\n", 8, ".nan", "wheel.noise_rad_s"},
      {"wheel_form_unknown", imu + "wheel:\n  form: twist\n", 8, "twist",
       "wheel.form: expected angular_rates, linear_speeds or speed_yaw_rate, found 'twist'"},
      {"speed_noise_zero", imu + "wheel:\n  form: linear_speeds\n  noise_m_s: 0\n", 9, "0",
       "wheel.noise_m_s: must be within [1e-06, 100] m/s"},
      {"yaw_noise_huge", imu + "wheel:\n  yaw_rate_noise_rad_s: 1e3\n", 8, "1e3",
       "wheel.yaw_rate_noise_rad_s: must be within"},
      {"controller_track_tiny",
       imu + "wheel:\n  form: speed_yaw_rate\n  controller_track_m: 0.001\n", 9, "0.001",
       "wheel.controller_track_m: must be within [0.05, 100] m"},
      {"controller_track_of_rates", imu + "wheel:\n  controller_track_m: 0.5\n", 8, "0.5",
       "only the form speed_yaw_rate has a controller track (wheel.form is angular_rates)"},
      {"lateral_slip_zero", imu + "wheel:\n  lateral_slip_sigma_m_s: 0\n", 8, "0",
       "wheel.lateral_slip_sigma_m_s: must be within [1e-06, 100] m/s"},
      {"compliance_negative", imu + "wheel:\n  cornering_compliance_rad_per_m_s2: -0.005\n", 8,
       "-0.005", "wheel.cornering_compliance_rad_per_m_s2: must be within [0, 1] rad/(m/s^2)"},
  };
  for (const Case& c : cases) {
    const std::string path = (test::OutputDir("dataset") / (c.name + ".yaml")).string();
    std::ofstream(path, std::ios::trunc) << c.text;
    try {
      ReadSensorsYaml(path);
      ADD_FAILURE() << c.name << ": accepted";
    } catch (const ParseError& e) {
      EXPECT_EQ(e.location().line, c.line) << c.name << ": " << e.what();
      // The value is the last thing on its line.
      size_t start = 0;
      for (int64_t i = 1; i < c.line; ++i) start = c.text.find('\n', start) + 1;
      const std::string line = c.text.substr(start, c.text.find('\n', start) - start);
      EXPECT_EQ(e.location().column, static_cast<int64_t>(line.rfind(c.value)) + 1)
          << c.name << ": " << e.what();
      EXPECT_THAT(e.detail(), HasSubstr(c.message)) << c.name;
    }
  }
}

// A dataset reads the wheel file its form names: the two other forms, written and read back.
TEST(DatasetTest, ReadsTheWheelFileItsFormNames) {
  const test_data::Drive drive = test_data::MakeDrive(1.0);
  for (sensors::WheelForm form :
       {sensors::WheelForm::kLinearSpeeds, sensors::WheelForm::kSpeedYawRate}) {
    const std::string name = sensors::WheelFormName(form);
    const fs::path directory = test::OutputDir("dataset") / ("form_" + name);
    fs::remove_all(directory);
    SensorsConfig config = drive.config;
    config.wheel->form = form;
    config.wheel->rate_hz = 50.0;
    if (form == sensors::WheelForm::kSpeedYawRate) config.wheel->controller_track_m = 0.555;
    sensors::WheelSpeedSamples speeds;
    sensors::OdometrySamples twist;
    for (const sensors::WheelSample& w : drive.wheel) {
      speeds.push_back({w.t_ns, 0.33 * w.left_rad_s, 0.33 * w.right_rad_s, false, 0.0, 0.0});
      twist.push_back({w.t_ns, 0.165 * (w.left_rad_s + w.right_rad_s),
                       0.33 * (w.right_rad_s - w.left_rad_s) / 0.555});
    }
    {
      DatasetWriter writer(directory.string());
      writer.WriteSensorsConfig(config);
      writer.WriteImu(drive.imu);
      if (form == sensors::WheelForm::kLinearSpeeds) {
        writer.WriteWheelSpeeds(speeds);
      } else {
        writer.WriteOdometry(twist);
      }
      writer.Close();
    }
    const Dataset dataset = ReadDataset(directory.string());
    EXPECT_EQ(dataset.wheel_form(), form) << name;
    ASSERT_TRUE(dataset.sensors.wheel.has_value());
    EXPECT_EQ(dataset.sensors.wheel->rate_hz, 50.0);
    EXPECT_EQ(dataset.sensors.wheel->controller_track_m, config.wheel->controller_track_m);
    EXPECT_TRUE(dataset.wheel.empty()) << name;
    EXPECT_EQ(dataset.wheel_sample_count(), drive.wheel.size()) << name;
    if (form == sensors::WheelForm::kLinearSpeeds) {
      ASSERT_EQ(dataset.wheel_speeds.size(), speeds.size());
      EXPECT_EQ(dataset.wheel_speeds[7].right_m_s, speeds[7].right_m_s);
      EXPECT_TRUE(dataset.odometry.empty());
    } else {
      ASSERT_EQ(dataset.odometry.size(), twist.size());
      EXPECT_EQ(dataset.odometry[7].yaw_rate_rad_s, twist[7].yaw_rate_rad_s);
      EXPECT_TRUE(dataset.wheel_speeds.empty());
    }
  }
}

// sensors.yaml names one form, the directory holds another form's file: one error naming both
// (a dataset imported before the form existed, or a file renamed by hand).
TEST(DatasetTest, FormAndFilesThatDisagreeAreRefused) {
  const test_data::Drive drive = test_data::MakeDrive(0.5);
  const fs::path directory = test::OutputDir("dataset") / "form_disagrees";
  fs::remove_all(directory);
  fs::create_directories(directory);
  std::ofstream(directory / "sensors.yaml")
      << "imu:\n  gyroscope_noise_density: 1.6968e-4\n  gyroscope_random_walk: 1.9393e-5\n"
         "  accelerometer_noise_density: 2.0e-3\n  accelerometer_random_walk: 3.0e-3\n"
         "  update_rate: 200\n";
  WriteImuCsv((directory / "imu.csv").string(), drive.imu);
  WriteOdometryCsv((directory / "odometry.csv").string(), {{drive.imu[0].t_ns, 0.5, 0.1}});
  try {
    ReadDataset(directory.string());
    FAIL() << "no error for odometry.csv under the default form";
  } catch (const ParseError& e) {
    EXPECT_EQ(e.location().file, (directory / "sensors.yaml").string());
    EXPECT_THAT(e.detail(),
                HasSubstr("the wheel form is angular_rates (no wheel section: the default), which "
                          "reads wheel.csv, but the dataset has no wheel.csv and has "
                          "odometry.csv: set wheel: {form: speed_yaw_rate} in sensors.yaml"));
  }
  // Named explicitly, the form reads; a form whose file is missing reads as no wheel data.
  std::ofstream(directory / "sensors.yaml", std::ios::app) << "wheel:\n  form: speed_yaw_rate\n";
  EXPECT_EQ(ReadDataset(directory.string()).odometry.size(), 1u);
  fs::remove(directory / "odometry.csv");
  EXPECT_EQ(ReadDataset(directory.string()).wheel_sample_count(), 0u);
  // Beside the form's own file, another form's file is left unread.
  WriteWheelCsv((directory / "wheel.csv").string(), drive.wheel);
  WriteOdometryCsv((directory / "odometry.csv").string(), {{drive.imu[0].t_ns, 0.5, 0.1}});
  const Dataset both = ReadDataset(directory.string());
  EXPECT_EQ(both.odometry.size(), 1u);
  EXPECT_TRUE(both.wheel.empty());
}

TEST(DatasetTest, ErrorsInAnyFileNameThatFile) {
  const std::string directory = WriteDrive("bad_wheel", test_data::MakeDrive(0.5));
  const std::string wheel = (fs::path(directory) / "wheel.csv").string();
  std::ofstream(wheel, std::ios::app) << "1,2\n";
  try {
    ReadDataset(directory);
    FAIL() << "no error for a short wheel.csv row";
  } catch (const ParseError& e) {
    EXPECT_EQ(e.location().file, wheel);
    EXPECT_THAT(e.detail(), HasSubstr("expected 3 columns"));
  }
}

TEST(DatasetTest, WriterRejectsOutOfOrderSweepsAndUseAfterClose) {
  const test_data::Drive drive = test_data::MakeDrive(0.5);
  const fs::path directory = test::OutputDir("dataset") / "writer_misuse";
  DatasetWriter writer(directory.string());
  writer.AddSweep(drive.sweeps[1]);
  EXPECT_THROW(writer.AddSweep(drive.sweeps[0]), Error);
  writer.Close();
  EXPECT_THROW(writer.WriteImu(drive.imu), Error);
}

// The writer refuses a sensors.yaml its reader would refuse, naming the field: a simulator or
// importer that states a zero sigma gets the error, not a dataset nothing can read.
TEST(DatasetTest, WriterRefusesASensorsFileItsReaderWouldRefuse) {
  test_data::Drive drive = test_data::MakeDrive(0.5);
  ASSERT_TRUE(drive.config.wheel.has_value());
  drive.config.wheel->noise_rad_s = 0.0;
  const fs::path directory = test::OutputDir("dataset") / "zero_wheel_sigma";
  fs::remove_all(directory);
  DatasetWriter writer(directory.string());
  try {
    writer.WriteSensorsConfig(drive.config);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), HasSubstr("wheel.noise_rad_s: must be within [1e-06, 100] rad/s"));
    EXPECT_THAT(e.what(), HasSubstr("outside what sensors.yaml may state"));
  }
  EXPECT_FALSE(fs::exists(directory / "sensors.yaml"));
  EXPECT_FALSE(fs::exists(directory / "sensors.yaml.new"));
  // A sensors.yaml written before stays as it was when a later configuration is refused.
  drive.config.wheel->noise_rad_s = 0.05;
  writer.WriteSensorsConfig(drive.config);
  drive.config.wheel->noise_rad_s = 0.0;
  EXPECT_THROW(writer.WriteSensorsConfig(drive.config), Error);
  EXPECT_EQ(ReadSensorsYaml((directory / "sensors.yaml").string()).wheel->noise_rad_s, 0.05);
  EXPECT_FALSE(fs::exists(directory / "sensors.yaml.new"));
}

TEST(DatasetTest, MissingDirectory) {
  EXPECT_THROW(ReadDataset((test::OutputDir("dataset") / "does_not_exist").string()), Error);
}

}  // namespace
}  // namespace io
}  // namespace autocal
