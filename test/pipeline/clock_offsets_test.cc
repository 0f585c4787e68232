// The wheel-IMU and GNSS-IMU clock offsets through the offline calibration without the LiDAR:
// initialized by cross-correlation (pipeline/clock_initialization.h), refined in the solve
// (Eq. K9), reported with sigma and observability in calibration.yaml.

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <iostream>
#include <string>

#include "autocal/io/calibration_yaml.h"
#include "autocal/io/problem_yaml.h"
#include "autocal/pipeline/offline_calibration.h"
#include "autocal/sim/simulator.h"
#include "pipeline/clock_initialization.h"
#include "pipeline/simulated_urban_dataset.h"
#include "support/test_paths.h"

namespace autocal {
namespace pipeline {
namespace {

constexpr double kWheelOffsetS = -0.2;  // the wheels stamp 0.2 s late
constexpr double kGnssOffsetS = 0.15;   // the receiver stamps 0.15 s early

// 40 s of the urban drive without the LiDAR (its roundabout from 18 s turns the car), the
// wheels and the GNSS receiver on clocks of their own.
sim::SimulationOptions ClockDriveOptions() {
  sim::SimulationOptions options = test::UrbanDriveOptions(40.0);
  options.lidar.enabled = false;
  options.wheel.time_offset_wheel_imu_s = kWheelOffsetS;
  options.gnss.time_offset_gnss_imu_s = kGnssOffsetS;
  return options;
}

class ClockOffsetsTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    data_ = new test::SimulatedUrbanDataset(ClockDriveOptions(), "clock_offsets");
  }
  static void TearDownTestSuite() {
    delete data_;
    data_ = nullptr;
  }
  static test::SimulatedUrbanDataset* data_;
};
test::SimulatedUrbanDataset* ClockOffsetsTest::data_ = nullptr;

// problems/imu_wheel_gnss.yaml with both clocks estimated.
io::Problem ClockProblem() {
  io::Problem problem = io::ReadProblemYaml(
      (std::filesystem::path(AUTOCAL_SOURCE_DIR) / "problems" / "imu_wheel_gnss.yaml").string());
  problem.calibration.time_offset_wheel_imu_s.mode = io::BlockMode::kEstimate;
  problem.calibration.time_offset_gnss_imu_s.mode = io::BlockMode::kEstimate;
  return problem;
}

// The cross-correlation alone starts both offsets near the truth: the wheel's from its yaw
// rate against the gyro, the GNSS's from the track's speed against the wheel speed.
TEST_F(ClockOffsetsTest, InitializationFindsBothOffsets) {
  const io::Dataset dataset = io::ReadDataset(data_->directory);
  sensors::Calibration calibration = dataset.sensors.nominal_calibration;
  std::vector<std::string> warnings;
  const ClockInitialization init =
      InitializeClockOffsets(dataset, ClockProblem(), &calibration, &warnings);
  EXPECT_THAT(warnings, ::testing::IsEmpty());
  ASSERT_TRUE(init.wheel.has_value());
  ASSERT_TRUE(init.gnss.has_value());
  std::cout << "wheel " << init.wheel->signal << " r " << init.wheel->estimate.peak_correlation
            << ": " << calibration.time_offset_wheel_imu_s * 1e3 << " ms; GNSS r "
            << init.gnss->peak_correlation << ": " << calibration.time_offset_gnss_imu_s * 1e3
            << " ms\n";
  EXPECT_NEAR(calibration.time_offset_wheel_imu_s, kWheelOffsetS, 0.02);
  EXPECT_NEAR(calibration.time_offset_gnss_imu_s, kGnssOffsetS, 0.05);
}

// Without wheel data the GNSS offset has nothing to be compared with: it keeps its nominal
// value, and the warning says so.
TEST_F(ClockOffsetsTest, GnssOffsetWithoutWheelsKeepsTheNominalWithAWarning) {
  const io::Dataset dataset = io::ReadDataset(data_->directory);
  io::Problem problem = ClockProblem();
  problem.sensors.wheel = false;
  sensors::Calibration calibration = dataset.sensors.nominal_calibration;
  std::vector<std::string> warnings;
  const ClockInitialization init =
      InitializeClockOffsets(dataset, problem, &calibration, &warnings);
  EXPECT_FALSE(init.wheel.has_value());
  EXPECT_EQ(calibration.time_offset_gnss_imu_s,
            dataset.sensors.nominal_calibration.time_offset_gnss_imu_s);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_THAT(warnings[0], ::testing::HasSubstr("GNSS-IMU time offset keeps its nominal"));
  EXPECT_THAT(warnings[0], ::testing::HasSubstr("no wheel data"));
}

// The solve refines both offsets; each error lies within 3 of its reported sigma, the sigmas
// are small enough to matter (observable) and calibration.yaml carries them.
TEST_F(ClockOffsetsTest, CalibratesBothOffsetsWithSigmaInCalibrationYaml) {
  const io::Dataset dataset = io::ReadDataset(data_->directory);
  const OfflineCalibrationResult result = CalibrateDataset(dataset, ClockProblem());
  std::cout << FormatCalibrationSummary(result);
  const sensors::Calibration& estimate = result.calibration.value;
  const io::CalibrationUncertainty& u = result.calibration.uncertainty;
  ASSERT_TRUE(u.time_offset_wheel_imu_s.sigma.has_value());
  ASSERT_TRUE(u.time_offset_gnss_imu_s.sigma.has_value());
  const double wheel_error_s = estimate.time_offset_wheel_imu_s - kWheelOffsetS;
  const double gnss_error_s = estimate.time_offset_gnss_imu_s - kGnssOffsetS;
  std::cout << "wheel offset error " << wheel_error_s * 1e3 << " ms (sigma "
            << *u.time_offset_wheel_imu_s.sigma * 1e3 << " ms), GNSS offset error "
            << gnss_error_s * 1e3 << " ms (sigma " << *u.time_offset_gnss_imu_s.sigma * 1e3
            << " ms)\n";
  EXPECT_LT(std::abs(wheel_error_s), 3.0 * *u.time_offset_wheel_imu_s.sigma);
  EXPECT_LT(std::abs(gnss_error_s), 3.0 * *u.time_offset_gnss_imu_s.sigma);
  EXPECT_EQ(u.time_offset_wheel_imu_s.observable, true);
  EXPECT_EQ(u.time_offset_gnss_imu_s.observable, true);

  const std::string directory =
      test::OutputDir("clock_offsets_result_" + std::to_string(static_cast<long>(getpid())))
          .string();
  std::filesystem::remove_all(directory);
  WriteCalibrationResult(directory, result);
  const io::CalibrationFile read =
      io::ReadCalibrationYaml((std::filesystem::path(directory) / "calibration.yaml").string());
  EXPECT_EQ(read.value.time_offset_wheel_imu_s, estimate.time_offset_wheel_imu_s);
  EXPECT_EQ(read.value.time_offset_gnss_imu_s, estimate.time_offset_gnss_imu_s);
  EXPECT_EQ(read.uncertainty.time_offset_wheel_imu_s.sigma, u.time_offset_wheel_imu_s.sigma);
  EXPECT_EQ(read.uncertainty.time_offset_gnss_imu_s.observable, true);
  std::filesystem::remove_all(directory);
}

}  // namespace
}  // namespace pipeline
}  // namespace autocal
