// Offline calibration without the LiDAR of logs whose wheels come as linear speeds
// (wheel_speed.csv) or as the odometry twist (odometry.csv): the form's blocks are estimated
// against the simulator's exact truth, and the sigma the calibration reports covers the error.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <optional>
#include <string>

#include "autocal/common/error.h"
#include "autocal/evaluation/calibration_errors.h"
#include "autocal/io/dataset.h"
#include "autocal/io/problem_yaml.h"
#include "autocal/pipeline/offline_calibration.h"
#include "autocal/sim/simulator.h"
#include "pipeline/simulated_urban_dataset.h"
#include "support/skid_steer_options.h"

namespace autocal {
namespace pipeline {
namespace {

io::Problem ImuWheelGnssProblem() { return test::ShippedProblem("imu_wheel_gnss.yaml"); }

// The urban drive (its roundabout excites the yaw rate) without the LiDAR, the wheels in
// `form`.
sim::SimulationOptions UrbanWithoutLidar(sensors::WheelForm form) {
  sim::SimulationOptions options = test::UrbanDriveOptions(34.0);
  options.lidar.enabled = false;
  options.wheel.config.form = form;
  return options;
}

// One estimated scalar block against its truth: |error| within 3 sigma, and the sigma small
// enough that the block counts as observed.
void ExpectCovered(const char* name, double estimate, double truth, const io::ScalarBlockInfo& u,
                   double max_sigma) {
  ASSERT_TRUE(u.sigma.has_value()) << name;
  std::cout << name << ": estimate " << estimate << ", truth " << truth << ", error "
            << estimate - truth << ", sigma " << *u.sigma << '\n';
  EXPECT_LT(*u.sigma, max_sigma) << name;
  EXPECT_LE(std::abs(estimate - truth), 3.0 * *u.sigma) << name;
  ASSERT_TRUE(u.observable.has_value()) << name;
  EXPECT_TRUE(*u.observable) << name;
}

// Odometry twist (test::UseOdometryTwist): k_v and b_eff come back within their sigma, 0.1 %
// and 5 mm at most (the observability limits of the speed scales and the track,
// problem_blocks.cc).
TEST(WheelFormsCalibration, OdometryTwistGivesSpeedScaleAndEffectiveTrack) {
  sim::SimulationOptions options = UrbanWithoutLidar(sensors::WheelForm::kSpeedYawRate);
  test::UseOdometryTwist(&options);
  const test::SimulatedUrbanDataset data(options, "wheel_twist");
  const io::Dataset dataset = io::ReadDataset(data.directory);
  ASSERT_EQ(dataset.wheel_form(), sensors::WheelForm::kSpeedYawRate);
  ASSERT_TRUE(dataset.wheel.empty());
  ASSERT_GT(dataset.odometry.size(), 3000u);
  const OfflineCalibrationResult result = CalibrateDataset(dataset, ImuWheelGnssProblem());
  std::cout << FormatCalibrationSummary(result);
  ASSERT_GT(result.whitened_residuals.count("wheel"), 0u);
  EXPECT_GE(result.whitened_residuals.at("wheel").after.size() / 4,
            result.trajectory.size() * 9 / 10);
  const sensors::Calibration& truth = data.simulator.true_calibration();
  const sensors::Calibration& estimate = result.calibration.value;
  const io::CalibrationUncertainty& u = result.calibration.uncertainty;
  ExpectCovered("odometry_speed_scale", estimate.odometry_speed_scale, truth.odometry_speed_scale,
                u.odometry_speed_scale, 0.001);
  ExpectCovered("effective_track_m", estimate.effective_track_m, truth.effective_track_m,
                u.effective_track_m, 0.005);
  // The blocks of the other forms take no part.
  const sensors::Calibration& nominal = dataset.sensors.nominal_calibration;
  EXPECT_EQ(estimate.wheel_radius_left_m, nominal.wheel_radius_left_m);
  EXPECT_EQ(estimate.track_width_m, nominal.track_width_m);
  EXPECT_EQ(estimate.wheel_speed_scale_left, nominal.wheel_speed_scale_left);
}

// The slow skid-steer robot (preset: 300 s at up to 1 m/s, IMU 30 Hz, odometry 10 Hz, GPS
// 2.5 Hz with 0.6 m sigma) as odometry twist, its clock offset left out (nothing models it
// here): k_v 0.97 and b_eff 1.875 times the physical track come back within 3 sigma of the
// truth. The drive determines them only partly (sigma 0.26 % and 63 mm, above the limits of
// 0.1 % and 5 % of the nominal b_eff): kept, not reported observable, and not held at the
// nominal value, which the data put 9 sigma away.
TEST(WheelFormsCalibration, SlowSkidSteerOdometryKeepsItsSpeedScaleAndEffectiveTrack) {
  sim::SimulationOptions options = sim::SkidSteerRobotOptions();
  options.wheel.config.form = sensors::WheelForm::kSpeedYawRate;
  options.wheel.time_offset_wheel_imu_s = 0.0;
  const test::SimulatedUrbanDataset data(options, "skid_steer_twist");
  const io::Dataset dataset = io::ReadDataset(data.directory);
  const OfflineCalibrationResult result = CalibrateDataset(dataset, ImuWheelGnssProblem());
  std::cout << FormatCalibrationSummary(result);
  const sensors::Calibration& truth = data.simulator.true_calibration();
  const sensors::Calibration& estimate = result.calibration.value;
  const io::CalibrationUncertainty& u = result.calibration.uncertainty;
  const auto expect_kept = [](const char* name, double estimate, double truth,
                              const io::ScalarBlockInfo& info, double max_sigma) {
    ASSERT_TRUE(info.sigma.has_value()) << name;
    std::cout << name << ": estimate " << estimate << ", truth " << truth << ", sigma "
              << *info.sigma << '\n';
    EXPECT_LT(*info.sigma, max_sigma) << name;
    EXPECT_LE(std::abs(estimate - truth), 3.0 * *info.sigma) << name;
  };
  expect_kept("odometry_speed_scale", estimate.odometry_speed_scale, truth.odometry_speed_scale,
              u.odometry_speed_scale, 0.005);
  expect_kept("effective_track_m", estimate.effective_track_m, truth.effective_track_m,
              u.effective_track_m, 0.1);
  EXPECT_GT(
      std::abs(estimate.effective_track_m - dataset.sensors.nominal_calibration.effective_track_m),
      0.3);
}

// The slow skid steer's 30 Hz IMU with 30 times the bench white noise (the vibration measured
// on the real robot), odometry twist at 10 Hz, no GNSS (problems/skid_steer_imu_odometry.yaml).
// The gyro's noise must not pass for excitation of the lever arm w x p_I_V (Eq. K14): every
// axis of T_I_V ends within 3 of its reported sigmas of the truth, and the rear axle's height
// above the IMU (its y; the flat drive never pitches or rolls) is not reported determined.
// Taking the noisy gyro as the rate put that y 32 cm from the truth at a stated 5.9 cm.
TEST(WheelFormsCalibration, NoisyGyroDoesNotPassForExcitationOfTheRearAxle) {
  const test::SimulatedUrbanDataset data(test::VibratingSkidSteerOdometryOptions(120.0, 3),
                                         "skid_steer_noisy_gyro");
  const io::Dataset dataset = io::ReadDataset(data.directory);
  const OfflineCalibrationResult result =
      CalibrateDataset(dataset, test::ShippedProblem("skid_steer_imu_odometry.yaml"));
  std::cout << FormatCalibrationSummary(result);
  const sensors::Calibration& truth = data.simulator.true_calibration();
  const sensors::Calibration& estimate = result.calibration.value;
  const io::PoseBlockInfo& u = result.calibration.uncertainty.T_I_V;
  ASSERT_TRUE(u.sigma_p_m.has_value());
  ASSERT_TRUE(u.sigma_rot_deg.has_value());
  ASSERT_EQ(u.observable.size(), 6u);
  const Eigen::Vector3d p_error_m = estimate.p_I_V - truth.p_I_V;
  const Eigen::Vector3d rot_error_deg =
      evaluation::CompareCalibration(estimate, truth).T_I_V.rotation_deg;
  for (int i = 0; i < 3; ++i) {
    std::cout << "axis " << i << ": p error " << p_error_m[i] << " m, sigma " << (*u.sigma_p_m)[i]
              << " m; rotation error " << rot_error_deg[i] << " deg, sigma "
              << (*u.sigma_rot_deg)[i] << " deg\n";
    EXPECT_LE(std::abs(p_error_m[i]), 3.0 * (*u.sigma_p_m)[i]) << i;
    EXPECT_LE(std::abs(rot_error_deg[i]), 3.0 * (*u.sigma_rot_deg)[i]) << i;
  }
  EXPECT_FALSE(u.observable[4]);
  EXPECT_GT((*u.sigma_p_m)[1], 0.1);
}

// The slow skid steer with GPS and the real robot's vibration (30 times the IMU's white
// noise), from problems/skid_steer_imu_odometry_gnss.yaml: its planar-rotation rows (Eq. F27)
// give the mount's roll and pitch from the turns. Both end within 3 of their reported sigmas
// of the truth (measured: 0.17 and -0.47 deg at 0.33 and 0.29 deg), at less than half the
// sigmas that gravity's up axis and the altitude leave without the rows (1.9 and 0.85 deg).
TEST(WheelFormsCalibration, TurnsGiveTheRigidRobotsMountTilt) {
  const test::SimulatedUrbanDataset data(test::VibratingSkidSteerOdometryOptions(120.0, 5),
                                         "skid_steer_turns");
  const io::Dataset dataset = io::ReadDataset(data.directory);
  const io::Problem with_rows = test::ShippedProblem("skid_steer_imu_odometry_gnss.yaml");
  ASSERT_EQ(with_rows.calibration.roll_pitch_rate_sigma_rad_s, std::optional<double>(0.0));
  io::Problem without_rows = with_rows;
  without_rows.calibration.roll_pitch_rate_sigma_rad_s.reset();
  const sensors::Calibration& truth = data.simulator.true_calibration();
  Eigen::Vector2d sigma_with_deg, sigma_without_deg;
  for (const io::Problem* problem : {&with_rows, static_cast<const io::Problem*>(&without_rows)}) {
    const OfflineCalibrationResult result = CalibrateDataset(dataset, *problem);
    const io::PoseBlockInfo& u = result.calibration.uncertainty.T_I_V;
    ASSERT_TRUE(u.sigma_rot_deg.has_value());
    ASSERT_EQ(u.observable.size(), 6u);
    const Eigen::Vector3d error_deg =
        evaluation::CompareCalibration(result.calibration.value, truth).T_I_V.rotation_deg;
    const bool rows = problem == &with_rows;
    (rows ? sigma_with_deg : sigma_without_deg) = u.sigma_rot_deg->head<2>();
    // The rows are reported as a residual group of their own, with the sigmas they used.
    EXPECT_EQ(result.whitened_residuals.count("planar_rotation"), rows ? 1u : 0u);
    EXPECT_EQ(result.calibration.solver.count("planar_rotation_sigma_rad_s"), rows ? 1u : 0u);
    std::cout << (rows ? "with" : "without") << " the rows: mount error (roll, pitch) "
              << error_deg.head<2>().transpose() << " deg, sigma "
              << u.sigma_rot_deg->head<2>().transpose() << " deg\n";
    if (!rows) continue;
    for (int i = 0; i < 2; ++i) {
      EXPECT_LE(std::abs(error_deg[i]), 3.0 * (*u.sigma_rot_deg)[i]) << i;
    }
  }
  for (int i = 0; i < 2; ++i) EXPECT_GT(sigma_without_deg[i], 2.0 * sigma_with_deg[i]) << i;
}

// CAN wheel speeds from wheels 1.2 % and 0.8 % larger than the vehicle assumes (scales
// 1.012, 0.992): both scales and the track width come back within their sigma.
TEST(WheelFormsCalibration, WheelSpeedsGiveSpeedScalesAndTrackWidth) {
  sim::SimulationOptions options = UrbanWithoutLidar(sensors::WheelForm::kLinearSpeeds);
  options.true_calibration.wheel_speed_scale_left = 1.012;
  options.true_calibration.wheel_speed_scale_right = 0.992;
  options.wheel.config.noise_m_s = 0.01;
  const test::SimulatedUrbanDataset data(options, "wheel_speeds");
  const io::Dataset dataset = io::ReadDataset(data.directory);
  ASSERT_EQ(dataset.wheel_form(), sensors::WheelForm::kLinearSpeeds);
  ASSERT_GT(dataset.wheel_speeds.size(), 3000u);
  const OfflineCalibrationResult result = CalibrateDataset(dataset, ImuWheelGnssProblem());
  std::cout << FormatCalibrationSummary(result);
  const sensors::Calibration& truth = data.simulator.true_calibration();
  const sensors::Calibration& estimate = result.calibration.value;
  const io::CalibrationUncertainty& u = result.calibration.uncertainty;
  ExpectCovered("wheel_speed_scale_left", estimate.wheel_speed_scale_left,
                truth.wheel_speed_scale_left, u.wheel_speed_scale_left, 0.001);
  ExpectCovered("wheel_speed_scale_right", estimate.wheel_speed_scale_right,
                truth.wheel_speed_scale_right, u.wheel_speed_scale_right, 0.001);
  ExpectCovered("track_width_m", estimate.track_width_m, truth.track_width_m, u.track_width_m,
                0.005);
  EXPECT_EQ(estimate.wheel_radius_left_m, dataset.sensors.nominal_calibration.wheel_radius_left_m);
}

// Odometry at 10 Hz, 1.2 ms off the keyframes' grid: a problem whose wheel gap is tighter
// than the samples' spacing gets no wheel factor, and the error names the form's file.
TEST(WheelFormsCalibration, CoverageErrorNamesTheFormsFile) {
  const test::SimulatedUrbanDataset data(UrbanWithoutLidar(sensors::WheelForm::kSpeedYawRate),
                                         "wheel_twist_plain");
  io::Dataset dataset = io::ReadDataset(data.directory);
  sensors::OdometrySamples sparse;
  for (size_t i = 0; i < dataset.odometry.size(); i += 10) {
    sparse.push_back(dataset.odometry[i]);
    sparse.back().t_ns += 1'234'567;
  }
  dataset.odometry = sparse;
  io::Problem tight = ImuWheelGnssProblem();
  tight.timing.max_wheel_gap_s = 0.02;
  try {
    CalibrateDataset(dataset, tight);
    ADD_FAILURE() << "a wheel gap of 20 ms must leave no wheel factor";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("wheel (10.0 Hz): 0 of "));
    EXPECT_THAT(e.what(), ::testing::HasSubstr("(odometry.csv: median interval 0.100 s"));
  }
}

// A drive that determines none of the estimated directions (a second of standing) leaves every
// block at its nominal value: the first warning says that nothing is calibrated.
TEST(WheelFormsCalibration, ADriveThatDeterminesNothingSaysNothingIsCalibrated) {
  sim::SimulationOptions options = UrbanWithoutLidar(sensors::WheelForm::kAngularRates);
  options.duration_s = 1.0;
  const test::SimulatedUrbanDataset data(options, "standing_second");
  const io::Dataset dataset = io::ReadDataset(data.directory);
  const OfflineCalibrationResult result =
      CalibrateDataset(dataset, test::ShippedProblem("skid_steer_imu_odometry.yaml"));
  const auto nothing =
      std::find_if(result.warnings.begin(), result.warnings.end(),
                   [](const std::string& w) { return w.rfind("nothing is calibrated: ", 0) == 0; });
  ASSERT_NE(nothing, result.warnings.end());
  EXPECT_THAT(*nothing, ::testing::HasSubstr("none of the 10 directions"));
  EXPECT_EQ(result.calibration.value.wheel_radius_left_m,
            dataset.sensors.nominal_calibration.wheel_radius_left_m);
}

}  // namespace
}  // namespace pipeline
}  // namespace autocal
