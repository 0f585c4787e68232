#include "autocal/pipeline/offline_calibration.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <iostream>
#include <optional>
#include <random>
#include <string>

#include "autocal/common/error.h"
#include "autocal/common/units.h"
#include "autocal/geometry/so3.h"
#include "autocal/io/calibration_yaml.h"
#include "autocal/io/problem_yaml.h"
#include "autocal/io/sensors_yaml.h"
#include "autocal/io/tum_trajectory.h"
#include "autocal/sensors/gnss_enu.h"
#include "autocal/sim/simulator.h"
#include "pipeline/gnss_noise_expectations.h"
#include "pipeline/simulated_urban_dataset.h"
#include "support/fixed_block_warnings.h"
#include "support/test_paths.h"

namespace autocal {
namespace pipeline {
namespace {

// A problem file shipped in problems/.
io::Problem ShippedProblem(const std::string& name) {
  return io::ReadProblemYaml(
      (std::filesystem::path(AUTOCAL_SOURCE_DIR) / "problems" / name).string());
}

// Every sensor, every block.
io::Problem FullProblem() { return ShippedProblem("urban_full.yaml"); }

// The LiDAR and the IMU only.
io::Problem LidarImuProblem() { return ShippedProblem("lidar_imu.yaml"); }

// Errors of the LiDAR-IMU blocks against the truth.
struct LidarImuErrors {
  double rotation_deg = 0.0;
  Eigen::Vector3d p_m = Eigen::Vector3d::Zero();
  double offset_ms = 0.0;
};

LidarImuErrors LidarImuErrorsOf(const sensors::Calibration& estimate,
                                const sensors::Calibration& truth) {
  LidarImuErrors e;
  e.rotation_deg = geometry::AngularDistance(estimate.q_I_L, truth.q_I_L) * kRadToDeg;
  e.p_m = estimate.p_I_L - truth.p_I_L;
  e.offset_ms = std::abs(estimate.time_offset_lidar_imu_s - truth.time_offset_lidar_imu_s) * 1e3;
  std::cout << "errors: rotation " << e.rotation_deg << " deg, p " << e.p_m.transpose()
            << " m, offset " << e.offset_ms << " ms\n";
  return e;
}

// Goals: 0.1 deg, 1 cm on the excited x and y, and the offset to 1 ms on this short log.
void ExpectLidarImuGoals(const LidarImuErrors& e) {
  EXPECT_LT(e.rotation_deg, 0.1);
  EXPECT_LT(e.p_m.head<2>().norm(), 0.01);
  EXPECT_LT(e.offset_ms, 1.0);
}

// RMS distance of the result's keyframes from the true IMU positions. The result is in ENU at
// the first fix, the truth in ENU at the simulator's origin.
double KeyframePositionRms(const OfflineCalibrationResult& result, const io::Dataset& dataset,
                           const sim::Simulator& simulator) {
  const sensors::EnuConverter enu = sensors::EnuConverter::AtFirstFix(dataset.gnss);
  const sim::GnssSimOptions& g = simulator.options().gnss;
  const sensors::EnuConverter sim_enu(g.origin_lat_deg, g.origin_lon_deg, g.origin_alt_m);
  double sum_m2 = 0.0;
  for (const auto& pose : result.trajectory) {
    const Eigen::Vector3d lla = enu.ToGeodetic(pose.T_W_I.p);
    const Eigen::Vector3d p_sim = sim_enu.ToEnu(lla.x(), lla.y(), lla.z());
    sum_m2 += (p_sim - simulator.ImuPoseAt(simulator.TimeOf(pose.t_ns)).p).squaredNorm();
  }
  const double rms_m = std::sqrt(sum_m2 / static_cast<double>(result.trajectory.size()));
  std::cout << "keyframe position RMS error " << rms_m << " m\n";
  return rms_m;
}

// The 34 s urban drive (test/pipeline/simulated_urban_dataset.h).
class OfflineCalibrationTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { data_ = new test::SimulatedUrbanDataset(34.0, "urban_34s"); }
  static void TearDownTestSuite() { delete data_; }
  static test::SimulatedUrbanDataset* data_;
};

test::SimulatedUrbanDataset* OfflineCalibrationTest::data_ = nullptr;

// The whole chain from the dataset on disk, with no guess from the user: the initializer
// replaces the nominal calibration, the batch refines it, the result is written and reads back.
TEST_F(OfflineCalibrationTest, CalibratesEveryBlockFromAllSensors) {
  const io::Dataset dataset = io::ReadDataset(data_->directory);
  OfflineCalibrationResult result = CalibrateDataset(dataset, FullProblem());
  std::cout << FormatCalibrationSummary(result);
  const sensors::Calibration& truth = data_->simulator.true_calibration();
  const sensors::Calibration& estimate = result.calibration.value;
  const LidarImuErrors errors = LidarImuErrorsOf(estimate, truth);
  const auto percent = [](double estimate, double truth) {
    return 100.0 * std::abs(estimate - truth) / truth;
  };
  std::cout << "radii " << percent(estimate.wheel_radius_left_m, truth.wheel_radius_left_m) << " % "
            << percent(estimate.wheel_radius_right_m, truth.wheel_radius_right_m)
            << " %, track width " << percent(estimate.track_width_m, truth.track_width_m)
            << " %, lever arm " << (estimate.p_I_A - truth.p_I_A).transpose() << " m\n";
  for (const std::string& w : result.warnings) std::cout << "warning: " << w << "\n";
  // Measured on this log: 0.077 deg; x, y within 6 mm; 0.44 ms; radii 0.005 % and 0.019 %;
  // lever arm x, y within 1 cm. Goals: 0.1 deg, 1 cm, 0.1 %, 2 cm; the offset (goal 0.5 ms on
  // the 60 s log, 0.10 ms there) is held to 1 ms on this 34 s log.
  ExpectLidarImuGoals(errors);
  EXPECT_LT(percent(estimate.wheel_radius_left_m, truth.wheel_radius_left_m), 0.1);
  EXPECT_LT(percent(estimate.wheel_radius_right_m, truth.wheel_radius_right_m), 0.1);
  EXPECT_LT((estimate.p_I_A - truth.p_I_A).head<2>().norm(), 0.02);
  // The fixes scatter as they state: their std stays (Eq. N2).
  EXPECT_EQ(result.calibration.residuals.at("gnss").at("noise_scale_horizontal"), 1.0);
  EXPECT_EQ(result.calibration.residuals.at("gnss").at("noise_scale_vertical"), 1.0);

  // Planar driving does not excite the LiDAR height nor the antenna height: reported and held
  // at the nominal value, not returned as noise.
  const io::CalibrationUncertainty& u = result.calibration.uncertainty;
  const sensors::Calibration& nominal = dataset.sensors.nominal_calibration;
  ASSERT_EQ(u.T_I_L.observable.size(), 6u);
  EXPECT_FALSE(u.T_I_L.observable[5]);
  EXPECT_DOUBLE_EQ(estimate.p_I_L.z(), nominal.p_I_L.z());
  ASSERT_EQ(u.p_I_A_m.observable.size(), 3u);
  EXPECT_FALSE(u.p_I_A_m.observable[2]);
  EXPECT_DOUBLE_EQ(estimate.p_I_A.z(), nominal.p_I_A.z());
  EXPECT_THAT(result.warnings, ::testing::Contains(::testing::HasSubstr("LiDAR z translation")));
  ASSERT_TRUE(u.T_I_L.sigma_rot_deg.has_value());
  ASSERT_TRUE(u.time_offset_lidar_imu_s.sigma.has_value());
  ASSERT_TRUE(u.wheel_radius_left_m.sigma.has_value());
  // The LiDAR's robust statistics: the Huber loss at 1 sigma down-weights the distances
  // beyond 2 sigma (4.6 % of a normal sample; wrong pairs add to them), and the others are
  // tighter than all of them.
  const std::map<std::string, double>& lidar = result.calibration.residuals.at("lidar");
  EXPECT_EQ(lidar.at("sigma_m"), result.batch.point_sigma_m);
  EXPECT_GT(lidar.at("points_downweighted_by_loss"), 0.02 * lidar.at("associated_points"));
  EXPECT_LT(lidar.at("points_downweighted_by_loss"), 0.15 * lidar.at("associated_points"));
  EXPECT_LT(lidar.at("rms_m_not_downweighted"), lidar.at("rms_m"));
  int beyond_two_sigma = 0;
  for (double r : result.batch.final_point_residuals_m) {
    if (std::abs(r) > 2.0 * result.batch.point_sigma_m) ++beyond_two_sigma;
  }
  EXPECT_EQ(lidar.at("points_downweighted_by_loss"), beyond_two_sigma);

  const std::string out = test::OutputDir("result").string();
  WriteCalibrationResult(out, result);
  const io::CalibrationFile read_back = io::ReadCalibrationYaml(out + "/calibration.yaml");
  EXPECT_TRUE(read_back.value.q_I_L.isApprox(estimate.q_I_L, 1e-12));
  EXPECT_EQ(io::ReadTumTrajectory(out + "/trajectory.tum").size(), result.trajectory.size());
  EXPECT_TRUE(std::filesystem::exists(out + "/calibration_per_iteration.csv"));
  EXPECT_GT(std::filesystem::file_size(out + "/report.html"), 1000u);
  ASSERT_FALSE(result.warnings.empty());  // the LiDAR's z, at least
  EXPECT_EQ(test::WarningsFileLines(out + "/warnings.txt"), result.warnings);
}

// A LiDAR that stamps each sweep when it ends, its points at negative times (as some drivers
// write them), records the same drive: the calibration meets the same goals. Measured: 0.021
// deg, x, y (-0.6, 6.5) mm, offset 0.45 ms off; stamped at the start, 0.020 deg, (-0.5, 6.3)
// mm, 0.47 ms.
TEST(OfflineCalibrationEndStamped, CalibratesSweepsStampedAtTheirEnd) {
  const test::SimulatedUrbanDataset data(test::EndStampedUrbanDriveOptions(34.0),
                                         "urban_34s_end_stamped");
  const io::Dataset dataset = io::ReadDataset(data.directory);
  ASSERT_LT(dataset.LoadSweep(0).cloud.time_s.maxCoeff(), 0.0);
  const OfflineCalibrationResult result = CalibrateDataset(dataset, FullProblem());
  ExpectLidarImuGoals(
      LidarImuErrorsOf(result.calibration.value, data.simulator.true_calibration()));
}

// The calibration takes no guess: a nominal calibration off by 20 deg, 0.3 m and 40 ms (the
// issue's bad guess) only sets the priors' centres and the values of unexcited directions.
// Wheels far noisier than sensors.yaml says (0.3 rad/s added per wheel against 0.02 stated):
// their yaw rate explains the gyro's to about 0.1 rad/s, and the LiDAR batch's wheel rows get
// sigmas scaled by that ratio, so that the radii's sigma covers what such wheels can tell.
TEST_F(OfflineCalibrationTest, NoisyWheelsGetTheNoiseTheDataShow) {
  io::Dataset dataset = io::ReadDataset(data_->directory);
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0.0, 0.3);
  for (sensors::WheelSample& w : dataset.wheel) {
    w.left_rad_s += noise(rng);
    w.right_rad_s += noise(rng);
  }
  const OfflineCalibrationResult result = CalibrateDataset(dataset, FullProblem());
  EXPECT_THAT(result.warnings,
              ::testing::Contains(::testing::HasSubstr("every wheel row's sigma is scaled")));
  const sensors::Calibration& truth = data_->simulator.true_calibration();
  const io::CalibrationUncertainty& u = result.calibration.uncertainty;
  ASSERT_TRUE(u.wheel_radius_left_m.sigma.has_value());
  const double error_m = result.calibration.value.wheel_radius_left_m - truth.wheel_radius_left_m;
  std::cout << "left radius " << error_m * 1e3 << " mm off, sigma "
            << *u.wheel_radius_left_m.sigma * 1e3 << " mm\n";
  EXPECT_LT(std::abs(error_m), 3.0 * *u.wheel_radius_left_m.sigma);
}

// The receiver states every fix's std four times too small: about the solve the fixes scatter
// about four times what they state, each axis group's sigma is scaled by what its rows show
// (Eq. N2), and the lever arm comes out as from the fixes as stated, with the LiDAR and
// without it. Measured: scales 3.96 horizontal and 3.50 vertical with the LiDAR, 3.65 and
// 3.56 without; the lever arm's sigma within 3 % of the stated run's, its value within
// 0.3 mm. Unscaled, its sigma was 29 % small with the LiDAR (5.6 against 7.9 mm), and without
// the LiDAR its x read observable at 13.9 mm where the fixes as stated leave it to its 3 cm
// prior.
TEST_F(OfflineCalibrationTest, OptimisticGnssStdGetsTheScatterTheFixesShow) {
  const io::Dataset as_stated = io::ReadDataset(data_->directory);
  const io::Dataset optimistic = test::WithOptimisticGnssStd(as_stated);
  for (const char* file : {"urban_full.yaml", "imu_wheel_gnss.yaml"}) {
    SCOPED_TRACE(file);
    const io::CalibrationFile stated =
        CalibrateDataset(as_stated, ShippedProblem(file)).calibration;
    const OfflineCalibrationResult result = CalibrateDataset(optimistic, ShippedProblem(file));
    EXPECT_THAT(
        result.warnings,
        ::testing::Contains(::testing::HasSubstr("the fixes scatter beyond their stated std")));
    const std::map<std::string, double>& gnss = result.calibration.residuals.at("gnss");
    std::cout << file << ": GNSS noise scale " << gnss.at("noise_scale_horizontal") << ", "
              << gnss.at("noise_scale_vertical") << "; lever arm sigma "
              << result.calibration.uncertainty.p_I_A_m.sigma.value().transpose() << " m against "
              << stated.uncertainty.p_I_A_m.sigma.value().transpose() << " m as stated, "
              << (result.calibration.value.p_I_A - stated.value.p_I_A).transpose()
              << " m from it\n";
    test::ExpectScaledGnssAndTheLeverArmAsStated(result.calibration, stated);
  }
}

// A solve of one outer iteration measures the fixes' scatter only after it: it says so, and
// records the scale the rows were weighed with (1).
TEST_F(OfflineCalibrationTest, OneOuterIterationSaysTheFixesScatterItCouldNotWeigh) {
  const io::Dataset dataset = test::WithOptimisticGnssStd(io::ReadDataset(data_->directory));
  io::Problem problem = FullProblem();
  problem.solver.outer_iterations = 1;
  const OfflineCalibrationResult result = CalibrateDataset(dataset, problem);
  EXPECT_THAT(result.warnings,
              ::testing::Contains(::testing::AllOf(
                  ::testing::HasSubstr("the fixes scatter beyond their stated std"),
                  ::testing::HasSubstr("raise solver.outer_iterations"))));
  const std::map<std::string, double>& gnss = result.calibration.residuals.at("gnss");
  EXPECT_EQ(gnss.at("noise_scale_horizontal"), 1.0);
  EXPECT_EQ(gnss.at("noise_scale_vertical"), 1.0);
}

TEST_F(OfflineCalibrationTest, ABadNominalGuessChangesNothingObservable) {
  io::Dataset dataset = io::ReadDataset(data_->directory);
  test::SpoilNominalGuess(&dataset.sensors);
  const sensors::Calibration& nominal = dataset.sensors.nominal_calibration;
  const OfflineCalibrationResult result = CalibrateDataset(dataset, FullProblem());
  const sensors::Calibration& estimate = result.calibration.value;
  // The same goals as from the simulator's nominal guess.
  ExpectLidarImuGoals(LidarImuErrorsOf(estimate, data_->simulator.true_calibration()));
  // The height the drive does not excite stays at the (bad) nominal value, and says so.
  EXPECT_FALSE(result.calibration.uncertainty.T_I_L.observable[5]);
  EXPECT_DOUBLE_EQ(estimate.p_I_L.z(), nominal.p_I_L.z());
}

// The outer loop stops at solver.outer_iterations converged or not; stopped after its coarse
// first iteration and one more, the estimate is still moving by much of its sigma, and the
// result says so (calibration.yaml and a warning) instead of presenting it as the solution.
TEST_F(OfflineCalibrationTest, SaysWhenTheOuterLoopStoppedShortOfConverging) {
  const io::Dataset dataset = io::ReadDataset(data_->directory);
  for (const int iterations : {1, 2}) {  // one: the change from the start
    io::Problem problem = LidarImuProblem();
    problem.solver.outer_iterations = iterations;
    const OfflineCalibrationResult stopped = CalibrateDataset(dataset, problem);
    EXPECT_FALSE(stopped.batch.converged);
    EXPECT_EQ(stopped.calibration.solver.at("outer_iterations_converged"), "false");
    EXPECT_THAT(stopped.warnings,
                ::testing::Contains(::testing::AllOf(
                    ::testing::HasSubstr("stopped at its " + std::to_string(iterations) +
                                         " outer iterations"),
                    ::testing::HasSubstr("sigma)"), ::testing::HasSubstr("raise solver"))));
  }
  // The same problem with its own outer_iterations converges and says nothing of it
  // (CalibratesTheLidarImuBlocksAlone).
}

// problems/lidar_imu.yaml: the LiDAR and the IMU alone. Without wheels and GNSS nothing but
// the IMU ties the velocity, so the translation is known less well (sigma 7-8 mm on this 34 s
// log, against 6 mm with every sensor); measured: 0.029 deg, x 4.4 mm, y 12.5 mm, 0.68 ms.
// The rotation and offset goals hold; the translation is held to its reported sigma (3 sigma)
// and to 2 cm. The wheel and GNSS blocks take no part and keep their nominal values.
TEST_F(OfflineCalibrationTest, CalibratesTheLidarImuBlocksAlone) {
  const io::Dataset dataset = io::ReadDataset(data_->directory);
  const OfflineCalibrationResult result = CalibrateDataset(dataset, LidarImuProblem());
  std::cout << FormatCalibrationSummary(result);
  EXPECT_TRUE(result.batch.converged);
  EXPECT_EQ(result.calibration.solver.at("outer_iterations_converged"), "true");
  // The odometry placed the keyframes: the rotation is not searched.
  EXPECT_FALSE(result.batch.rotation_search.searched);
  EXPECT_THAT(result.warnings,
              ::testing::Not(::testing::Contains(::testing::HasSubstr("outer iterations"))));
  const sensors::Calibration& estimate = result.calibration.value;
  const sensors::Calibration& nominal = dataset.sensors.nominal_calibration;
  const LidarImuErrors e = LidarImuErrorsOf(estimate, data_->simulator.true_calibration());
  EXPECT_LT(e.rotation_deg, 0.1);
  EXPECT_LT(e.offset_ms, 1.0);
  const io::PoseBlockInfo& info = result.calibration.uncertainty.T_I_L;
  ASSERT_TRUE(info.sigma_p_m.has_value());
  for (int a = 0; a < 2; ++a) {
    EXPECT_LT(std::abs(e.p_m(a)), 0.02) << "axis " << a;
    EXPECT_LT(std::abs(e.p_m(a)), 3.0 * (*info.sigma_p_m)(a)) << "axis " << a;
  }
  EXPECT_EQ(estimate.wheel_radius_left_m, nominal.wheel_radius_left_m);
  EXPECT_EQ(estimate.p_I_A, nominal.p_I_A);
  EXPECT_FALSE(result.calibration.uncertainty.p_I_A_m.sigma.has_value());
  EXPECT_EQ(result.whitened_residuals.count("gnss"), 0u);
}

// The log holds moving vehicles (LiDAR points on them break the static-world model) and GNSS
// multipath (2 % of the fixes 3-15 m off). CalibratesEveryBlockFromAllSensors shows the
// robust losses of the problem keep every goal; here the same log with plain least squares
// everywhere shows what they protect against.
TEST_F(OfflineCalibrationTest, WithoutRobustLossesTheOutliersDoDamage) {
  ASSERT_GT(data_->summary.gnss_outliers, 0) << "the log must hold multipath fixes";
  const sensors::Calibration& truth = data_->simulator.true_calibration();
  const io::Dataset dataset = io::ReadDataset(data_->directory);
  // With the problem's losses the lever arm meets its goal on this very log ...
  const sensors::Calibration robust = CalibrateDataset(dataset, FullProblem()).calibration.value;
  const double robust_error_m = (robust.p_I_A - truth.p_I_A).head<2>().norm();
  EXPECT_LT(robust_error_m, 0.02);
  // ... and without them it does not: under the weak default prior (no stated lever-arm
  // uncertainty) the run completes, and the lever arm shows the damage.
  io::Problem problem = FullProblem();
  problem.loss = factors::FactorLossOptions();
  problem.loss.wheel = factors::LossOptions();
  problem.loss.gnss = factors::LossOptions();
  problem.loss.lidar = factors::LossOptions();
  io::Dataset unstated = dataset;
  unstated.sensors.nominal_uncertainty.p_I_A_m = io::VectorBlockInfo();
  const OfflineCalibrationResult result = CalibrateDataset(unstated, problem);
  const sensors::Calibration& estimate = result.calibration.value;
  const double lever_arm_error_m = (estimate.p_I_A - truth.p_I_A).head<2>().norm();
  const double rotation_error_deg =
      geometry::AngularDistance(estimate.q_I_L, truth.q_I_L) * kRadToDeg;
  std::cout << "lever arm x-y error " << robust_error_m << " m with the losses, "
            << lever_arm_error_m << " m without; T_I_L rotation error without "
            << rotation_error_deg << " deg\n";
  RecordProperty("lever_arm_xy_error_mm", std::to_string(1e3 * lever_arm_error_m));
  // The multipath fixes drag the lever arm beyond its 2 cm goal, several times the robust
  // solve's error.
  EXPECT_GT(lever_arm_error_m, 0.02);
  EXPECT_GT(lever_arm_error_m, 4.0 * robust_error_m);
}

// A nominal lever arm 20 cm off in x, stated to 1 cm: the drive determines the lever arm to
// about that, so the solve lands many prior sigmas from the stated value. The run is refused
// with the direction named; a compromise between the data and a wrong prior is not a result.
TEST_F(OfflineCalibrationTest, RefusesAResultFarOutsideAStatedPrior) {
  io::Dataset dataset = io::ReadDataset(data_->directory);
  test::MisstateNominalLeverArm(&dataset.sensors, 0.20, 0.01);
  try {
    CalibrateDataset(dataset, FullProblem());
    FAIL() << "a lever arm far outside its stated prior was returned as a result";
  } catch (const Error& e) {
    std::cout << e.what() << "\n";
    EXPECT_THAT(e.what(), ::testing::HasSubstr("did not converge to a plausible result"));
    EXPECT_THAT(e.what(), ::testing::HasSubstr("GNSS antenna x lever arm (IMU frame) moved"));
    EXPECT_THAT(e.what(), ::testing::Not(::testing::HasSubstr("GNSS antenna y lever arm")));
  }
}

// A 30 s highway drive (seed 3, about 120 km/h, no turns, traffic around the car) with
// problems/highway.yaml. The LiDAR odometry does not follow it (a featureless road and cars
// moving with it): the keyframes are rebuilt from GNSS and the IMU, and the result says so.
// The drive excites the wheel radii (speed against GNSS and the IMU) and nothing else to the
// accuracy goals: every other direction is reported by name, held at its nominal value where
// the drive left it at its prior, and what is reported observable meets the goals.
TEST(OfflineCalibrationHighway, ReportsAndHoldsWhatTheDriveDoesNotExcite) {
  const test::SimulatedUrbanDataset data(test::HighwayDriveOptions(30.0, 3), "highway_30s");
  const sim::Simulator& simulator = data.simulator;
  const io::Dataset dataset = io::ReadDataset(data.directory);
  const io::Problem problem = ShippedProblem("highway.yaml");
  const OfflineCalibrationResult result = CalibrateDataset(dataset, problem);
  std::cout << FormatCalibrationSummary(result);
  for (const std::string& w : result.warnings) std::cout << "warning: " << w << "\n";

  EXPECT_THAT(
      result.warnings,
      ::testing::Contains(::testing::HasSubstr("the LiDAR odometry did not follow the drive")));
  const sensors::Calibration& truth = simulator.true_calibration();
  const sensors::Calibration& nominal = dataset.sensors.nominal_calibration;
  const sensors::Calibration& estimate = result.calibration.value;
  const io::CalibrationUncertainty& u = result.calibration.uncertainty;

  // Held at the nominal value and named: the LiDAR translation and the antenna, which the
  // drive leaves at their priors.
  ASSERT_EQ(u.T_I_L.observable.size(), 6u);
  for (size_t a = 3; a < 6; ++a) EXPECT_FALSE(u.T_I_L.observable[a]);
  EXPECT_EQ(estimate.p_I_L, nominal.p_I_L);
  EXPECT_EQ(estimate.p_I_A, nominal.p_I_A);
  EXPECT_THAT(result.warnings, ::testing::Contains(::testing::HasSubstr(
                                   "LiDAR x translation (IMU frame): not excited by the drive")));
  // Partly determined, kept at the estimate and not reported observable: the LiDAR pitch and
  // yaw and the time offset (no turns), and the roll (measured 0.014 deg off at sigma 0.14 deg
  // here), which meets the goal whenever it is reported observable.
  const Eigen::Vector3d delta_deg =
      geometry::Log(estimate.q_I_L.conjugate() * truth.q_I_L) * kRadToDeg;
  const Eigen::Vector3d sigma_deg = *u.T_I_L.sigma_rot_deg;
  std::cout << "LiDAR rotation error " << delta_deg.transpose() << " deg at sigma "
            << sigma_deg.transpose() << " deg\n";
  for (size_t a = 1; a < 3; ++a) EXPECT_FALSE(u.T_I_L.observable[a]);
  for (int a = 0; a < 3; ++a) {
    EXPECT_LT(std::abs(delta_deg(a)), 3.0 * sigma_deg(a)) << "axis " << a;
    if (u.T_I_L.observable[static_cast<size_t>(a)]) {
      EXPECT_LT(std::abs(delta_deg(a)), 0.1) << "axis " << a;
    }
  }
  EXPECT_EQ(u.time_offset_lidar_imu_s.observable, false);
  EXPECT_THAT(
      result.warnings,
      ::testing::Contains(::testing::HasSubstr("LiDAR-IMU time offset: only partly determined")));

  // Observable: the radii, within the goal (measured 0.0019 % and 0.0000 %); and whatever
  // else is reported observable meets its goal.
  const auto percent = [](double estimate, double truth) {
    return 100.0 * std::abs(estimate - truth) / truth;
  };
  EXPECT_EQ(u.wheel_radius_left_m.observable, true);
  EXPECT_EQ(u.wheel_radius_right_m.observable, true);
  EXPECT_LT(percent(estimate.wheel_radius_left_m, truth.wheel_radius_left_m), 0.1);
  EXPECT_LT(percent(estimate.wheel_radius_right_m, truth.wheel_radius_right_m), 0.1);
  if (u.track_width_m.observable.value_or(false)) {
    EXPECT_LT(percent(estimate.track_width_m, truth.track_width_m), 0.5);
  }
  ASSERT_EQ(u.p_I_A_m.observable.size(), 3u);
  for (size_t a = 0; a < 3; ++a) EXPECT_FALSE(u.p_I_A_m.observable[a]);

  // The keyframes follow the drive (measured 4.1 cm RMS: the antenna lever arm and the LiDAR
  // extrinsic are held at nominal values a few cm off).
  ASSERT_FALSE(result.trajectory.empty());
  const double rms_m = KeyframePositionRms(result, dataset, simulator);
  EXPECT_LT(rms_m, 0.1);
}

// A 30 s highway drive whose nominal LiDAR yaw is 4 deg off (seed 4, 16 beams). Straight at
// 33 m/s, the partners 3 to 20 keyframes away lie 20 to 130 m down the road, and that yaw puts
// their barrier points metres from any plane: only the pairs the error left near their planes
// remained, and the yaw stayed where it started (the same drive from autocal_simulate: 4.25 deg
// off at a stated sigma of 0.115 deg, 37 sigma). The
// nearest sweeps, tried by every point the far partners did not pair, hold the barriers and
// move the yaw to the truth (pairing_options.h, fallback_partner_offsets).
TEST(OfflineCalibrationHighway, FindsALidarYawDegreesOffItsNominalValue) {
  const test::SimulatedUrbanDataset data(test::HighwayDriveOptions(30.0, 4), "highway_30s_yaw");
  const io::Dataset dataset = io::ReadDataset(data.directory);
  const sensors::Calibration& truth = data.simulator.true_calibration();
  const Eigen::Vector3d nominal_deg =
      geometry::Log(dataset.sensors.nominal_calibration.q_I_L.conjugate() * truth.q_I_L) *
      kRadToDeg;
  ASSERT_GT(std::abs(nominal_deg.z()), 3.0) << "the drive no longer starts the yaw far off";

  const OfflineCalibrationResult result = CalibrateDataset(dataset, ShippedProblem("highway.yaml"));
  // The right perturbation at the estimate, the sigmas' (q_truth = q_estimate Exp(delta)).
  const Eigen::Vector3d delta_deg =
      geometry::Log(result.calibration.value.q_I_L.conjugate() * truth.q_I_L) * kRadToDeg;
  const Eigen::Vector3d sigma_deg = *result.calibration.uncertainty.T_I_L.sigma_rot_deg;
  std::cout << "LiDAR rotation: nominal " << nominal_deg.transpose() << " deg off, estimate "
            << delta_deg.transpose() << " deg off at sigma " << sigma_deg.transpose() << " deg\n";
  // Measured: yaw 0.030 deg at sigma 0.111 deg (pitch -0.051 at 0.171, roll -0.186 at 0.126).
  EXPECT_LT(std::abs(delta_deg.z()), 3.0 * sigma_deg.z());
  EXPECT_LT(std::abs(delta_deg.z()), 0.5);
  for (int a = 0; a < 2; ++a) EXPECT_LT(std::abs(delta_deg(a)), 3.0 * sigma_deg(a)) << a;
}

// A highway drive whose few turns and slow attitude changes barely determine the LiDAR-IMU
// time offset: the offset's Jacobian takes the gyroscope's mean over a sweep (docs/estimation.md,
// Eq. P1b). With the rate of a single sample its noise counted as information and this drive
// ended 6.2 ms off at a stated sigma of 1.51 ms (4.1 sigma); the same drive with the IMU's
// white noise a hundredth (sensors.yaml unchanged) has sigma 1.94 ms.
TEST(OfflineCalibrationHighway, TheTimeOffsetsSigmaCoversItsErrorOnAWeakDrive) {
  const test::SimulatedUrbanDataset data(test::HighwayDriveOptions(30.0, 5), "highway_30s_offset");
  const io::Dataset dataset = io::ReadDataset(data.directory);
  const OfflineCalibrationResult result = CalibrateDataset(dataset, ShippedProblem("highway.yaml"));
  const double error_ms = 1e3 * (result.calibration.value.time_offset_lidar_imu_s -
                                 data.simulator.true_calibration().time_offset_lidar_imu_s);
  ASSERT_TRUE(result.calibration.uncertainty.time_offset_lidar_imu_s.sigma.has_value());
  const double sigma_ms = 1e3 * *result.calibration.uncertainty.time_offset_lidar_imu_s.sigma;
  std::cout << "time offset " << error_ms << " ms off at sigma " << sigma_ms << " ms\n";
  // Measured: 5.0 ms off at sigma 1.94 ms (2.6 sigma).
  EXPECT_LT(std::abs(error_ms), 3.0 * sigma_ms);
}

// A 5 Hz LiDAR, every sweep a keyframe: a sweep's IMU motion table spans 0.2 s, and the
// attitude error its points share through it (the gyroscope's integrated white noise) is
// smallest with the keyframe at the sweep's middle (docs/estimation.md, Eq. P1c). With the
// keyframe 20 ms before the first point this drive's LiDAR roll ended 3.8 sigma off (0.43 deg
// at a stated 0.11 deg); measured now: 0.13 deg at 0.13 deg.
TEST(OfflineCalibrationHighway, TheLidarRollsSigmaCoversItsErrorWithLongSweeps) {
  sim::SimulationOptions options = test::HighwayDriveOptions(30.0, 4);
  options.lidar.config.rate_hz = 5.0;
  const test::SimulatedUrbanDataset data(options, "highway_30s_5hz");
  const io::Dataset dataset = io::ReadDataset(data.directory);
  io::Problem problem = ShippedProblem("highway.yaml");
  problem.lidar.sweep_stride = 1;
  const OfflineCalibrationResult result = CalibrateDataset(dataset, problem);
  const Eigen::Vector3d delta_deg = geometry::Log(result.calibration.value.q_I_L.conjugate() *
                                                  data.simulator.true_calibration().q_I_L) *
                                    kRadToDeg;
  ASSERT_TRUE(result.calibration.uncertainty.T_I_L.sigma_rot_deg.has_value());
  const Eigen::Vector3d sigma_deg = *result.calibration.uncertainty.T_I_L.sigma_rot_deg;
  std::cout << "LiDAR rotation " << delta_deg.transpose() << " deg off at sigma "
            << sigma_deg.transpose() << " deg\n";
  for (int a = 0; a < 3; ++a) EXPECT_LT(std::abs(delta_deg(a)), 2.0 * sigma_deg(a)) << a;
}

// The same drive with every fourth sweep a keyframe (a 5 Hz LiDAR at the problem's stride 2
// alike): the nearest keyframes lie 13 m apart, the 4 deg yaw moves their barrier points by
// 0.9 m, beyond even the first coarse gate, and the yaw stayed where it started (the same drive
// from autocal_simulate: 4.1 deg off at a stated sigma of 0.13 deg, 31 sigma; five coarse
// levels instead of three did not find it). The nominal rotation, which no turn checked, is
// searched before the solve (docs/estimation.md, Eq. P12).
TEST(OfflineCalibrationHighway, SearchesANominalLidarRotationThatSparseKeyframesMiss) {
  const test::SimulatedUrbanDataset data(test::HighwayDriveOptions(30.0, 4), "highway_30s_yaw");
  const io::Dataset dataset = io::ReadDataset(data.directory);
  const sensors::Calibration& truth = data.simulator.true_calibration();
  io::Problem problem = ShippedProblem("highway.yaml");
  problem.lidar.sweep_stride = 4;

  const OfflineCalibrationResult result = CalibrateDataset(dataset, problem);
  const Eigen::Vector3d delta_deg =
      geometry::Log(result.calibration.value.q_I_L.conjugate() * truth.q_I_L) * kRadToDeg;
  const Eigen::Vector3d sigma_deg = *result.calibration.uncertainty.T_I_L.sigma_rot_deg;
  std::cout << "LiDAR rotation " << delta_deg.transpose() << " deg off at sigma "
            << sigma_deg.transpose() << " deg\n";
  // Measured: roll 0.25 deg off at sigma 0.13, pitch -0.03 at 0.18, yaw -0.10 at 0.13.
  for (int a = 0; a < 3; ++a) EXPECT_LT(std::abs(delta_deg(a)), 3.0 * sigma_deg(a)) << a;
  EXPECT_LT(std::abs(delta_deg.z()), 0.5);
  EXPECT_THAT(result.warnings, ::testing::Contains(::testing::AllOf(
                                   ::testing::HasSubstr("the LiDAR rotation's nominal value"),
                                   ::testing::HasSubstr("the solve started there"))));
}

TEST_F(OfflineCalibrationTest, RefusesWhatTheDatasetCannotGive) {
  io::Dataset dataset = io::ReadDataset(data_->directory);
  dataset.wheel.clear();
  io::Problem problem = LidarImuProblem();
  problem.sensors.wheel = true;
  try {
    CalibrateDataset(dataset, problem);
    FAIL() << "a problem with wheels on a dataset without them was accepted";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("wheel"));
  }
  // The rows' scatter over the log (Eq. C8) needs two stretches and a significance.
  for (const auto& [stretches, significance] :
       {std::pair{1, 0.001}, std::pair{-2, 0.001}, std::pair{16, 0.0}, std::pair{16, 1.0}}) {
    OfflineCalibrationOptions options;
    options.scatter_stretches = stretches;
    options.scatter_significance = significance;
    EXPECT_THROW(CalibrateDataset(io::ReadDataset(data_->directory), LidarImuProblem(), options),
                 Error)
        << stretches << ", " << significance;
  }
  // Without the LiDAR the keyframes come from the GNSS track or the wheels: one is required.
  io::Problem imu_alone = LidarImuProblem();
  imu_alone.sensors.lidar = false;
  imu_alone.sensors.gnss = false;
  imu_alone.calibration.T_I_L.rotation.mode = io::BlockMode::kFixed;
  imu_alone.calibration.T_I_L.translation.mode = io::BlockMode::kFixed;
  imu_alone.calibration.time_offset_lidar_imu_s.mode = io::BlockMode::kFixed;
  try {
    CalibrateDataset(io::ReadDataset(data_->directory), imu_alone);
    FAIL() << "a problem with the IMU alone was accepted";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("needs GNSS"));
    EXPECT_THAT(e.what(), ::testing::HasSubstr("or the wheels"));
  }
}

// A sensor with fewer factors than the scatter test's stretches is not tested (Eq. C8): the run
// says so rather than reporting no scatter.
TEST_F(OfflineCalibrationTest, SaysWhichSensorsTheScatterTestLeavesOut) {
  OfflineCalibrationOptions options;
  options.scatter_stretches = 500;
  const OfflineCalibrationResult result =
      CalibrateDataset(io::ReadDataset(data_->directory), LidarImuProblem(), options);
  const auto untested = [&](const std::string& sensor) {
    return std::any_of(result.warnings.begin(), result.warnings.end(), [&](const std::string& w) {
      return w.rfind(sensor + " rows: ", 0) == 0 &&
             w.find("fewer than the 500 stretches") != std::string::npos;
    });
  };
  EXPECT_TRUE(untested("imu"));  // one factor per keyframe, about 170
  const auto imu = result.calibration.residuals.find("imu");
  EXPECT_FALSE(imu != result.calibration.residuals.end() &&
               imu->second.count("stretch_scatter_ratio") > 0);
}

// Without a position reference (no GNSS, no LiDAR) the keyframes are dead reckoned from the IMU
// and the wheels, the first one's position and yaw the gauge: the yaw rows still tie the radii
// to the track (their ratio), gravity the mount's roll and pitch, and the drive reports what it
// cannot determine rather than a value.
TEST_F(OfflineCalibrationTest, WithoutGnssTheWheelsDeadReckon) {
  const io::Dataset dataset = io::ReadDataset(data_->directory);
  io::Problem problem = ShippedProblem("imu_wheel_gnss.yaml");
  problem.sensors.gnss = false;
  problem.calibration.p_I_A_m.mode = io::BlockMode::kFixed;
  const OfflineCalibrationResult result = CalibrateDataset(dataset, problem);
  std::cout << FormatCalibrationSummary(result);
  const sensors::Calibration& truth = data_->simulator.true_calibration();
  const sensors::Calibration& estimate = result.calibration.value;
  const io::CalibrationUncertainty& u = result.calibration.uncertainty;
  EXPECT_TRUE(result.gnss_positions_W.empty());
  EXPECT_FALSE(result.calibration.solver.count("gnss_factors"));
  EXPECT_THAT(result.warnings, ::testing::Contains(::testing::HasSubstr("no position reference")));
  // Every block within what it reports: an observable or kept value within 4 sigma of the
  // truth, a held one at its prior.
  const auto within = [](double error, double sigma, const char* what) {
    EXPECT_LT(std::abs(error), 4.0 * sigma) << what << ": error " << error << ", sigma " << sigma;
  };
  within(estimate.wheel_radius_left_m - truth.wheel_radius_left_m, *u.wheel_radius_left_m.sigma,
         "left radius");
  within(estimate.wheel_radius_right_m - truth.wheel_radius_right_m, *u.wheel_radius_right_m.sigma,
         "right radius");
  within(estimate.track_width_m - truth.track_width_m, *u.track_width_m.sigma, "track");
  const Eigen::Vector3d mount_error =
      -geometry::Log(Eigen::Quaterniond(estimate.q_I_V.conjugate() * truth.q_I_V));
  for (int a = 0; a < 3; ++a) {
    within(mount_error(a), kDegToRad * (*u.T_I_V.sigma_rot_deg)(a), "mount");
  }
  // The ratio of radius to track is what the yaw rows see: better than either.
  const double ratio_error = estimate.wheel_radius_left_m / estimate.track_width_m /
                                 (truth.wheel_radius_left_m / truth.track_width_m) -
                             1.0;
  std::cout << "radius / track " << 100.0 * ratio_error << " %\n";
  EXPECT_LT(std::abs(ratio_error), 0.01);
  // The trajectory: relative to the first keyframe, close to the truth's shape over the drive.
  ASSERT_GT(result.trajectory.size(), 300u);
}

// Eq. C7: a problem that fixes the mount at a nominal value the drive contradicts hears of
// it, per direction and by how much; fixed at the truth, it hears nothing.
TEST_F(OfflineCalibrationTest, SaysWhenTheDriveContradictsAFixedMount) {
  io::Dataset dataset = io::ReadDataset(data_->directory);
  io::Problem problem = ShippedProblem("imu_wheel_gnss.yaml");
  problem.calibration.T_I_V.rotation.mode = io::BlockMode::kFixed;
  const sensors::Calibration& truth = data_->simulator.true_calibration();
  const Eigen::Vector3d nominal_error_deg =
      geometry::Log(
          Eigen::Quaterniond(dataset.sensors.nominal_calibration.q_I_V.conjugate() * truth.q_I_V)) *
      kRadToDeg;
  std::cout << "truth - nominal mount (deg): " << nominal_error_deg.transpose() << "\n";
  ASSERT_GT(std::abs(nominal_error_deg.y()), 1.0);  // the simulator's nominal is off in pitch

  const std::optional<test::FixedDirectionStep> pitch = test::StepOfFixedDirection(
      test::FixedDirectionWarnings(CalibrateDataset(dataset, problem).warnings),
      "mount pitch (about the vehicle's left axis)");
  ASSERT_TRUE(pitch.has_value());
  // Where the data put it: the truth, within the step's sigma (measured: 2.48 deg, sigma
  // 0.086 deg, for 2.51 deg).
  EXPECT_NEAR(pitch->step, nominal_error_deg.y(), 0.25);
  dataset.sensors.nominal_calibration.q_I_V = truth.q_I_V;
  EXPECT_THAT(test::FixedDirectionWarnings(CalibrateDataset(dataset, problem).warnings),
              ::testing::IsEmpty());
}

// problems/imu_wheel_gnss.yaml with one solver round of two iterations: enough to run every
// step, cheap enough for the bad-input tests below.
io::Problem QuickImuWheelGnssProblem() {
  io::Problem problem = ShippedProblem("imu_wheel_gnss.yaml");
  problem.solver.max_iterations = 2;
  problem.solver.outer_iterations = 1;
  return problem;
}

// datasets/README.md lets sensors.yaml leave out its wheel: section: the wheel factors then
// take the encoder noise of sensors/sensor_config.h. It used to dereference the empty section
// (garbage noise, "Residual and Jacobian evaluation failed" after the whole setup).
TEST_F(OfflineCalibrationTest, WithoutAWheelSectionTheEncoderDefaultsServe) {
  // The log's IMU, wheels and GNSS with a sensors.yaml that has no wheel: section.
  const std::filesystem::path directory =
      test::OutputDir("no_wheel_section_" + std::to_string(static_cast<long>(getpid())));
  std::filesystem::remove_all(directory);
  std::filesystem::create_directories(directory);
  for (const char* file : {"imu.csv", "wheel.csv", "gnss.csv"}) {
    std::filesystem::copy_file(std::filesystem::path(data_->directory) / file, directory / file);
  }
  io::Dataset dataset = io::ReadDataset(data_->directory);
  io::SensorsConfig without_wheel = dataset.sensors;
  without_wheel.wheel.reset();
  io::WriteSensorsYaml((directory / "sensors.yaml").string(), without_wheel);
  const io::Dataset defaulted_dataset = io::ReadDataset(directory.string());
  ASSERT_FALSE(defaulted_dataset.sensors.wheel.has_value());

  const io::Problem problem = QuickImuWheelGnssProblem();
  const OfflineCalibrationResult defaulted = CalibrateDataset(defaulted_dataset, problem);
  dataset.sensors.wheel = sensors::WheelConfig();
  const OfflineCalibrationResult stated = CalibrateDataset(dataset, problem);
  std::filesystem::remove_all(directory);
  EXPECT_EQ(defaulted.calibration.value.wheel_radius_left_m,
            stated.calibration.value.wheel_radius_left_m);
  EXPECT_EQ(defaulted.calibration.value.track_width_m, stated.calibration.value.track_width_m);
  ASSERT_TRUE(defaulted.whitened_residuals.count("wheel"));
  EXPECT_EQ(defaulted.whitened_residuals.at("wheel").after,
            stated.whitened_residuals.at("wheel").after);
}

// Wheel stamps in microseconds never meet the IMU's: refused before any work, naming the file
// and the likely unit, instead of a result that silently left the wheels out.
TEST_F(OfflineCalibrationTest, RefusesWheelStampsOutsideTheImuTimeSpan) {
  io::Dataset dataset = io::ReadDataset(data_->directory);
  for (sensors::WheelSample& w : dataset.wheel) w.t_ns /= 1000;
  try {
    CalibrateDataset(dataset, QuickImuWheelGnssProblem());
    FAIL() << "wheel stamps in microseconds were accepted";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("uses the wheel encoders but 0 of " +
                                               std::to_string(dataset.wheel.size()) +
                                               " samples of " + data_->directory +
                                               "/wheel.csv fall inside the IMU's time span"));
    EXPECT_THAT(e.what(), ::testing::HasSubstr("the stamps look like microseconds"));
  }
}

// The message of the error CalibrateDataset throws, or a failure when it throws none.
std::string CalibrationError(const io::Dataset& dataset, const io::Problem& problem) {
  try {
    CalibrateDataset(dataset, problem);
  } catch (const Error& e) {
    return e.what();
  }
  ADD_FAILURE() << "the calibration was accepted";
  return "";
}

// Wheel samples over the first 30 % of the log only: most keyframes get no wheel factor. A
// result would present wheel blocks as calibrated from the log while they saw a third of it:
// the run fails with the sensor, its rate, the count and the limits, and writes nothing.
TEST_F(OfflineCalibrationTest, FailsWhenTheWheelsCoverTooFewKeyframes) {
  io::Dataset dataset = io::ReadDataset(data_->directory);
  dataset.wheel.resize(dataset.wheel.size() * 3 / 10);
  const std::string what = CalibrationError(dataset, QuickImuWheelGnssProblem());
  EXPECT_THAT(what, ::testing::MatchesRegex(
                        ".*: wheel \\(100\\.0 Hz\\): [0-9]+ of [0-9]+ keyframes bracketed within "
                        "max_wheel_gap_s = 0\\.025 s \\(and IMU samples within max_imu_gap_s = "
                        "0\\.0125 s, IMU at 200\\.0 Hz\\), fewer than timing\\.min_factor_fraction "
                        "= 0\\.50 of the [0-9]+ it could serve .*; nothing is written"));
  // The problem may accept less.
  io::Problem lenient = QuickImuWheelGnssProblem();
  lenient.timing.min_factor_fraction = 0.2;
  EXPECT_NO_THROW(CalibrateDataset(dataset, lenient));
}

// Wheel samples at 10 Hz, 1.2 ms off the keyframes' 0.1 s grid: the gap derived from their
// rate (Eq. T1, 0.25 s) brackets every keyframe, where the former fixed 25 ms bracketed none.
// A problem file that sets a tighter gap gets none, and the error says so with the figures.
TEST_F(OfflineCalibrationTest, WheelGapFollowsTheirRateUnlessTheProblemSetsIt) {
  io::Dataset dataset = io::ReadDataset(data_->directory);
  sensors::WheelSamples sparse;
  for (size_t i = 0; i < dataset.wheel.size(); i += 10) {
    sparse.push_back(dataset.wheel[i]);
    sparse.back().t_ns += 1'234'567;
  }
  dataset.wheel = sparse;
  const OfflineCalibrationResult result = CalibrateDataset(dataset, QuickImuWheelGnssProblem());
  const size_t keyframes = result.trajectory.size();
  EXPECT_GE(result.whitened_residuals.at("wheel").after.size() / 4, keyframes * 9 / 10);
  io::Problem tight = QuickImuWheelGnssProblem();
  tight.timing.max_wheel_gap_s = 0.02;
  const std::string what = CalibrationError(dataset, tight);
  EXPECT_THAT(what, ::testing::HasSubstr("wheel (10.0 Hz): 0 of " + std::to_string(keyframes) +
                                         " keyframes bracketed within max_wheel_gap_s = 0.020 s"));
  EXPECT_THAT(what, ::testing::HasSubstr("(wheel.csv: median interval 0.100 s, p99 0.100 s"));
}

// A slower platform's sensors (IMU 100 Hz, wheels 10 Hz, GNSS 1 Hz) calibrate without the
// LiDAR from limits derived from their rates: keyframes every 0.5 s (Eq. T2), a track window
// of +-2.5 s (T3), wheel and IMU factors at 90 % of the keyframes or more, and each fix in one
// GNSS factor (Eq. K17; interpolated to every keyframe, a fix entered three rows, and the rows
// scattered at 1.96 of their sigma with the line between fixes missing the turning antenna).
TEST(OfflineCalibrationSlowSensors, CalibratesWithoutTheLidarFromTheirRates) {
  sim::SimulationOptions options = test::UrbanDriveOptions(34.0);
  options.lidar.enabled = false;
  options.imu.noise.update_rate_hz = 100.0;
  options.wheel.config.rate_hz = 10.0;
  options.gnss.config.rate_hz = 1.0;
  options.gnss.num_outages = 0;
  const test::SimulatedUrbanDataset data(options, "slow_sensors");
  const io::Dataset dataset = io::ReadDataset(data.directory);
  const OfflineCalibrationResult result =
      CalibrateDataset(dataset, ShippedProblem("imu_wheel_gnss.yaml"));
  std::cout << FormatCalibrationSummary(result);
  const size_t keyframes = result.trajectory.size();
  ASSERT_GT(keyframes, 60u);
  EXPECT_EQ(result.trajectory[1].t_ns - result.trajectory[0].t_ns, 500'000'000);
  const size_t wheel = result.whitened_residuals.at("wheel").after.size() / 4;
  const size_t gnss = result.whitened_residuals.at("gnss").after.size() / 3;
  const size_t imu = result.whitened_residuals.at("imu").after.size() / 15;
  std::cout << keyframes << " keyframes: " << wheel << " wheel, " << gnss << " GNSS, " << imu
            << " IMU factors\n";
  EXPECT_GE(wheel * 10, keyframes * 9);
  const int64_t half_ns = 250'000'000;
  const size_t fixes = static_cast<size_t>(
      std::count_if(dataset.gnss.begin(), dataset.gnss.end(), [&](const sensors::GnssFix& f) {
        return f.t_ns >= result.trajectory.front().t_ns - half_ns &&
               f.t_ns <= result.trajectory.back().t_ns + half_ns;
      }));
  EXPECT_LE(gnss, fixes);
  EXPECT_GE(gnss * 10, fixes * 9);
  EXPECT_EQ(imu, keyframes - 1);
  const sensors::Calibration& truth = data.simulator.true_calibration();
  const sensors::Calibration& estimate = result.calibration.value;
  const auto percent = [](double estimate, double truth) {
    return 100.0 * std::abs(estimate - truth) / truth;
  };
  std::cout << "radii " << percent(estimate.wheel_radius_left_m, truth.wheel_radius_left_m) << " % "
            << percent(estimate.wheel_radius_right_m, truth.wheel_radius_right_m) << " %\n";
  // The issue's goal for the radii and the other test's for the keyframes (measured 0.023 % and
  // 0.028 %, 4.6 cm RMS; with every fix interpolated to every keyframe 0.065 %, 0.072 %, 5.1 cm).
  EXPECT_LT(percent(estimate.wheel_radius_left_m, truth.wheel_radius_left_m), 0.1);
  EXPECT_LT(percent(estimate.wheel_radius_right_m, truth.wheel_radius_right_m), 0.1);
  EXPECT_LT(KeyframePositionRms(result, dataset, data.simulator), 0.1);

  // With both clocks estimated each fix serves one keyframe (docs/keyframe_factors.md, Eq.
  // K17): at 1 Hz half of them, which the coverage check counts against the fixes the log has,
  // not the keyframes. With three fixes lost it refused the run ("32 of 69 keyframes ...,
  // fewer than timing.min_factor_fraction = 0.50"). The clocks end within three sigmas.
  io::Problem clocks = ShippedProblem("imu_wheel_gnss.yaml");
  clocks.calibration.time_offset_wheel_imu_s.mode = io::BlockMode::kEstimate;
  clocks.calibration.time_offset_gnss_imu_s.mode = io::BlockMode::kEstimate;
  io::Dataset fewer_fixes = dataset;
  fewer_fixes.gnss.erase(fewer_fixes.gnss.begin() + 10, fewer_fixes.gnss.begin() + 13);
  EXPECT_NO_THROW(CalibrateDataset(fewer_fixes, clocks));
  const OfflineCalibrationResult timed = CalibrateDataset(dataset, clocks);
  const size_t fixes_used = timed.whitened_residuals.at("gnss").factors / 2;  // 2 blocks a fix
  const io::CalibrationUncertainty& u = timed.calibration.uncertainty;
  ASSERT_TRUE(u.time_offset_wheel_imu_s.sigma && u.time_offset_gnss_imu_s.sigma);
  std::cout << fixes_used << " fixes of " << keyframes << " keyframes; clocks "
            << timed.calibration.value.time_offset_wheel_imu_s * 1e3 << " ms (sigma "
            << *u.time_offset_wheel_imu_s.sigma * 1e3 << ") and "
            << timed.calibration.value.time_offset_gnss_imu_s * 1e3 << " ms (sigma "
            << *u.time_offset_gnss_imu_s.sigma * 1e3 << ")\n";
  EXPECT_GE(fixes_used * 20, keyframes * 9);
  EXPECT_LE(fixes_used * 2, keyframes + 1);
  EXPECT_LT(std::abs(timed.calibration.value.time_offset_wheel_imu_s),
            3.0 * *u.time_offset_wheel_imu_s.sigma);
  EXPECT_LT(std::abs(timed.calibration.value.time_offset_gnss_imu_s),
            3.0 * *u.time_offset_gnss_imu_s.sigma);
}

// problems/imu_wheel_gnss.yaml on the same log: keyframes every 0.1 s from GNSS and the IMU,
// then wheel radii, track width, the vehicle rotation and the lever arm with every state. The
// LiDAR blocks take no part and keep their nominal values.
TEST_F(OfflineCalibrationTest, WithoutTheLidarFromImuWheelsAndGnss) {
  const io::Dataset dataset = io::ReadDataset(data_->directory);
  const io::Problem problem = ShippedProblem("imu_wheel_gnss.yaml");
  const OfflineCalibrationResult result = CalibrateDataset(dataset, problem);
  std::cout << FormatCalibrationSummary(result);
  const sensors::Calibration& truth = data_->simulator.true_calibration();
  const sensors::Calibration& nominal = dataset.sensors.nominal_calibration;
  const sensors::Calibration& estimate = result.calibration.value;
  const io::CalibrationUncertainty& u = result.calibration.uncertainty;
  const auto percent = [](double estimate, double truth) {
    return 100.0 * std::abs(estimate - truth) / truth;
  };
  const double vehicle_rotation_deg =
      geometry::AngularDistance(estimate.q_I_V, truth.q_I_V) * kRadToDeg;
  std::cout << "radii " << percent(estimate.wheel_radius_left_m, truth.wheel_radius_left_m) << " % "
            << percent(estimate.wheel_radius_right_m, truth.wheel_radius_right_m)
            << " %, track width " << percent(estimate.track_width_m, truth.track_width_m)
            << " %, lever arm " << (estimate.p_I_A - truth.p_I_A).transpose()
            << " m, T_I_V rotation " << vehicle_rotation_deg << " deg\n";
  // The goals of the issue for the wheel blocks and the lever arm.
  EXPECT_LT(percent(estimate.wheel_radius_left_m, truth.wheel_radius_left_m), 0.1);
  EXPECT_LT(percent(estimate.wheel_radius_right_m, truth.wheel_radius_right_m), 0.1);
  ASSERT_TRUE(u.wheel_radius_left_m.observable.has_value());
  EXPECT_TRUE(*u.wheel_radius_left_m.observable);
  if (u.track_width_m.observable.value_or(false)) {
    EXPECT_LT(percent(estimate.track_width_m, truth.track_width_m), 0.5);
  }
  // The lever arm: y is excited by the turns (measured 9 mm off, sigma 9.8 mm); x less so
  // (sigma 1.8 cm against the 3 cm prior: held), z not at all. Whatever is reported observable
  // meets the 2 cm goal.
  ASSERT_EQ(u.p_I_A_m.observable.size(), 3u);
  EXPECT_TRUE(u.p_I_A_m.observable[1]);
  for (int a = 0; a < 3; ++a) {
    if (u.p_I_A_m.observable[static_cast<size_t>(a)]) {
      EXPECT_LT(std::abs(estimate.p_I_A(a) - truth.p_I_A(a)), 0.02) << "axis " << a;
    }
  }
  // The LiDAR blocks are the nominal ones.
  EXPECT_TRUE(estimate.q_I_L.isApprox(nominal.q_I_L, 1e-15));
  EXPECT_EQ(estimate.p_I_L, nominal.p_I_L);
  EXPECT_EQ(estimate.time_offset_lidar_imu_s, nominal.time_offset_lidar_imu_s);
  EXPECT_FALSE(u.T_I_L.sigma_rot_deg.has_value());
  // The keyframes follow the true trajectory.
  ASSERT_GT(result.trajectory.size(), 300u);
  const double rms_m = KeyframePositionRms(result, dataset, data_->simulator);
  EXPECT_LT(rms_m, 0.1);
  // Residuals per sensor, before and after.
  for (const char* sensor : {"imu", "wheel", "gnss"}) {
    ASSERT_TRUE(result.whitened_residuals.count(sensor)) << sensor;
    EXPECT_FALSE(result.whitened_residuals.at(sensor).after.empty()) << sensor;
    EXPECT_EQ(result.whitened_residuals.at(sensor).before.size(),
              result.whitened_residuals.at(sensor).after.size());
  }
  EXPECT_GT(result.calibration.residuals.at("gnss").at("whitened_rms"), 0.0);
  // The multipath fixes carry the plain RMS; without them the fixes fit their stated noise.
  const std::map<std::string, double>& gnss = result.calibration.residuals.at("gnss");
  EXPECT_GT(gnss.at("outlier_rows"), 0.0);
  EXPECT_LT(gnss.at("outlier_rows"), 0.05 * gnss.at("rows"));
  EXPECT_GT(gnss.at("whitened_robust_sigma"), 0.7);
  EXPECT_LT(gnss.at("whitened_robust_sigma"), 1.3);
  EXPECT_EQ(gnss.at("noise_scale_horizontal"), 1.0);
  EXPECT_EQ(gnss.at("noise_scale_vertical"), 1.0);
  EXPECT_LT(gnss.at("whitened_rms_without_outliers"), 1.3);
  EXPECT_GT(gnss.at("whitened_rms"), 3.0 * gnss.at("whitened_rms_without_outliers"));
  // The IMU's and the wheels' rows are of several kinds: no robust statistics for them.
  EXPECT_FALSE(result.calibration.residuals.at("imu").count("whitened_robust_sigma"));
  // The factors the Cauchy loss down-weighted (weight below one half): the multipath fixes
  // and the noise's tail, a few percent; the others fit their stated noise. The IMU has no
  // loss: none down-weighted.
  // Two blocks per fix, its horizontal rows and its vertical row (factors::GnssAxes).
  EXPECT_EQ(gnss.at("factors") * 3.0, gnss.at("rows") * 2.0);
  EXPECT_GE(gnss.at("factors_downweighted_by_loss"), gnss.at("outlier_rows") / 2.0);
  EXPECT_LT(gnss.at("factors_downweighted_by_loss"), 0.1 * gnss.at("factors"));
  EXPECT_LT(gnss.at("whitened_rms_not_downweighted"), 1.2);
  EXPECT_EQ(result.calibration.residuals.at("imu").at("factors_downweighted_by_loss"), 0.0);
  EXPECT_EQ(result.calibration.residuals.at("imu").at("whitened_rms_not_downweighted"),
            result.calibration.residuals.at("imu").at("whitened_rms"));
  EXPECT_THAT(result.warnings,
              ::testing::Not(::testing::Contains(::testing::HasSubstr("the joint solve stopped"))));
}

// One radius for both wheels: calibration.yaml gives the right wheel that estimate with its
// sigma and flag, not a value without a sigma that reads as a fixed block.
TEST_F(OfflineCalibrationTest, ASharedRadiusIsWrittenForBothWheels) {
  const io::Dataset dataset = io::ReadDataset(data_->directory);
  io::Problem problem = ShippedProblem("imu_wheel_gnss.yaml");
  problem.calibration.wheel_radius_shared = true;
  const OfflineCalibrationResult result = CalibrateDataset(dataset, problem);
  const io::CalibrationUncertainty& u = result.calibration.uncertainty;
  ASSERT_TRUE(u.wheel_radius_left_m.sigma.has_value());
  EXPECT_EQ(u.wheel_radius_right_m.sigma, u.wheel_radius_left_m.sigma);
  EXPECT_EQ(u.wheel_radius_right_m.observable, u.wheel_radius_left_m.observable);
  EXPECT_EQ(result.calibration.value.wheel_radius_right_m,
            result.calibration.value.wheel_radius_left_m);
}

// Without the LiDAR, a joint solve cut off at its iteration limit says so, as the LiDAR runs'
// outer loop does: its values and sigma are those of a point short of the minimum.
TEST_F(OfflineCalibrationTest, WithoutTheLidarSaysWhenTheSolveStoppedAtItsLimit) {
  const io::Dataset dataset = io::ReadDataset(data_->directory);
  io::Problem problem = ShippedProblem("imu_wheel_gnss.yaml");
  problem.solver.max_iterations = 2;
  problem.solver.outer_iterations = 1;
  const OfflineCalibrationResult result = CalibrateDataset(dataset, problem);
  EXPECT_THAT(result.batch.termination, ::testing::HasSubstr("Maximum number of iterations"));
  EXPECT_THAT(result.warnings,
              ::testing::Contains(::testing::HasSubstr(
                  "the joint solve stopped at its iteration limit (2) before converging")));
  // The file counts the solve's iterations as the warning does (Ceres' list of them starts
  // with the evaluation at the start).
  EXPECT_EQ(result.calibration.solver.at("iterations"), "2");
}

}  // namespace
}  // namespace pipeline
}  // namespace autocal
