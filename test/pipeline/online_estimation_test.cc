#include "autocal/pipeline/online_estimation.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <utility>

#include "autocal/common/error.h"
#include "autocal/common/time.h"
#include "autocal/common/units.h"
#include "autocal/evaluation/trajectory_errors.h"
#include "autocal/geometry/so3.h"
#include "autocal/io/calibration_yaml.h"
#include "autocal/io/tum_trajectory.h"
#include "autocal/pipeline/offline_calibration.h"
#include "autocal/sim/simulator.h"
#include "pipeline/gnss_noise_expectations.h"
#include "pipeline/simulated_urban_dataset.h"
#include "support/test_paths.h"

namespace autocal {
namespace pipeline {
namespace {

// Every sensor, every block (problems/urban_full.yaml with fewer points per sweep, to keep the
// test short). The vehicle frame is estimated, as in every shipped problem: held at the
// simulator's nominal, 0.5 deg off in yaw and 2.5 deg in pitch, it would turn the keyframes'
// heading with it under a road car's lateral rows (Eq. K6c; measured: q_I_L 0.35 deg at the end
// instead of 0.07 deg).
io::Problem FullProblem() {
  io::Problem problem;
  problem.path = "urban_full (test)";
  problem.lidar.max_points_per_sweep = 250;
  return problem;
}

// The true position at t_ns, interpolated in the dataset's ground truth.
Eigen::Vector3d TruePosition(const io::Trajectory& truth, int64_t t_ns) {
  auto it = std::lower_bound(truth.begin(), truth.end(), t_ns,
                             [](const io::TrajectorySample& s, int64_t t) { return s.t_ns < t; });
  const size_t i1 = std::min(static_cast<size_t>(it - truth.begin()), truth.size() - 1);
  const size_t i0 = i1 == 0 ? 0 : i1 - 1;
  const double s = i1 == i0 ? 0.0
                            : static_cast<double>(t_ns - truth[i0].t_ns) /
                                  static_cast<double>(truth[i1].t_ns - truth[i0].t_ns);
  return (1.0 - s) * truth[i0].T_W_I.p + s * truth[i1].T_W_I.p;
}

// Errors of an online run against the dataset's ground truth.
struct OnlineErrors {
  double max_position_m = 0.0;
  double rms_position_m = 0.0;
  double initial_rotation_deg = 0.0;  // q_I_L after the initializer
  double rotation_deg = 0.0;          // q_I_L at the end
  Eigen::Vector3d p_I_L_m = Eigen::Vector3d::Zero();
  double offset_ms = 0.0;
};

OnlineErrors ErrorsOf(const OnlineEstimationResult& result, const io::Dataset& dataset,
                      const sensors::Calibration& truth) {
  // W is the ENU frame at the first (noisy) fix, the ground truth's is the simulator's ENU
  // origin: the two differ by a translation, removed as the mean difference.
  Eigen::Vector3d mean_difference = Eigen::Vector3d::Zero();
  for (const io::TrajectorySample& s : result.trajectory) {
    mean_difference += s.T_W_I.p - TruePosition(dataset.groundtruth_trajectory, s.t_ns);
  }
  mean_difference /= static_cast<double>(result.trajectory.size());
  OnlineErrors e;
  double sum_sq = 0.0;
  for (const io::TrajectorySample& s : result.trajectory) {
    const Eigen::Vector3d truth_p = TruePosition(dataset.groundtruth_trajectory, s.t_ns);
    const double d = (s.T_W_I.p - truth_p - mean_difference).norm();
    e.max_position_m = std::max(e.max_position_m, d);
    sum_sq += d * d;
  }
  e.rms_position_m = std::sqrt(sum_sq / static_cast<double>(result.trajectory.size()));
  const sensors::Calibration& estimate = result.calibration.value;
  e.rotation_deg = geometry::AngularDistance(estimate.q_I_L, truth.q_I_L) * kRadToDeg;
  e.initial_rotation_deg = geometry::AngularDistance(result.initial.q_I_L, truth.q_I_L) * kRadToDeg;
  e.p_I_L_m = estimate.p_I_L - truth.p_I_L;
  e.offset_ms = 1e3 * std::abs(estimate.time_offset_lidar_imu_s - truth.time_offset_lidar_imu_s);
  std::cout << result.trajectory.size() << " keyframes in " << result.seconds_total
            << " s (initializer " << result.seconds_initialization << " s), frames "
            << mean_difference.transpose() << " m apart, position error max " << e.max_position_m
            << " m, rms " << e.rms_position_m << " m; q_I_L " << e.initial_rotation_deg << " -> "
            << e.rotation_deg << " deg, p_I_L " << e.p_I_L_m.transpose() << " m, offset "
            << e.offset_ms << " ms\n";
  return e;
}

// Measured from the simulator's nominal guess: 0.044 m max, 0.023 m rms; q_I_L 3.06 -> 0.066
// deg (initializer on every second sweep, turned about the vertical by the GNSS-inertial
// start -> window), p_I_L (0.9, 0.6, 0.8) cm, offset 0.16 ms. This 30 s drive with 16 beams
// and 250 points per sweep leaves the window short of the trajectory goals;
// test/accuracy/online_estimation_urban_test.cc checks them on a 60 s log.
void ExpectOnlineGoals(const OnlineErrors& e) {
  EXPECT_LT(e.max_position_m, 0.25);
  EXPECT_LT(e.rms_position_m, 0.1);
  EXPECT_LT(e.rotation_deg, 0.3);
  EXPECT_LT(e.p_I_L_m.head<2>().norm(), 0.03);
  EXPECT_LT(e.offset_ms, 1.5);
}

// The 30 s urban drive (test/pipeline/simulated_urban_dataset.h).
class OnlineEstimationTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { data_ = new test::SimulatedUrbanDataset(30.0, "urban_30s"); }
  static void TearDownTestSuite() { delete data_; }
  static test::SimulatedUrbanDataset* data_;
};

test::SimulatedUrbanDataset* OnlineEstimationTest::data_ = nullptr;

// The dataset on disk streamed through the window from the initializer's start; the result
// files are written and read back.
TEST_F(OnlineEstimationTest, StreamsDatasetAndWritesResult) {
  const io::Dataset dataset = io::ReadDataset(data_->directory);
  int progress_calls = 0;
  OnlineEstimationOptions options;
  options.progress = [&progress_calls](const OnlineEstimationProgress& p) {
    ++progress_calls;
    EXPECT_GE(p.log_fraction, 0.0);
    EXPECT_LE(p.log_fraction, 1.0);
  };
  const OnlineEstimationResult result = EstimateDatasetOnline(dataset, FullProblem(), options);
  const sensors::Calibration& truth = data_->simulator.true_calibration();
  const sensors::Calibration& estimate = result.calibration.value;
  const OnlineErrors e = ErrorsOf(result, dataset, truth);
  EXPECT_EQ(static_cast<int64_t>(result.trajectory.size()), result.counters.updates + 1);
  EXPECT_EQ(static_cast<int64_t>(result.calibration_over_time.size()), result.counters.updates);
  EXPECT_EQ(progress_calls, result.counters.updates);
  EXPECT_GT(result.counters.updates, 250);
  EXPECT_GT(result.counters.marginalizations, 0);
  EXPECT_GT(result.seconds_initialization, 0.0);
  EXPECT_LT(result.seconds_initialization, result.seconds_total);
  ExpectOnlineGoals(e);
  ASSERT_TRUE(result.calibration.uncertainty.T_I_L.sigma_rot_deg.has_value());
  EXPECT_GT(result.calibration.uncertainty.T_I_L.sigma_rot_deg->minCoeff(), 0.0);
  EXPECT_TRUE(result.calibration.uncertainty.p_I_A_m.sigma.has_value());
  EXPECT_TRUE(result.calibration.uncertainty.T_I_V.sigma_rot_deg.has_value());  // estimated
  // The estimate's steps move as its covariance says on a simulated drive (Eq. W9): tested,
  // nothing widened.
  EXPECT_GT(result.calibration.residuals.at("window").at("step_scatter_ratio"), 0.0);
  EXPECT_THAT(result.warnings, ::testing::Not(::testing::Contains(::testing::HasSubstr("W9"))));

  const std::string out = test::OutputDir("online_result").string();
  WriteOnlineEstimationResult(out, result);
  const io::CalibrationFile read_back = io::ReadCalibrationYaml(out + "/calibration.yaml");
  EXPECT_TRUE(read_back.value.q_I_L.isApprox(estimate.q_I_L, 1e-12));
  EXPECT_EQ(io::ReadTumTrajectory(out + "/trajectory.tum").size(), result.trajectory.size());
  // The smoothed trajectory: the same stamps, closer to the truth (measured: ATE 2.2 -> 1.2 cm,
  // 0.115 -> 0.073 deg).
  ASSERT_EQ(result.smoothed_trajectory.size(), result.trajectory.size());
  const io::Trajectory smoothed = io::ReadTumTrajectory(out + "/trajectory_smoothed.tum");
  ASSERT_EQ(smoothed.size(), result.trajectory.size());
  for (size_t i = 0; i < smoothed.size(); ++i) {
    ASSERT_EQ(smoothed[i].t_ns, result.trajectory[i].t_ns);
  }
  const evaluation::TrajectoryErrors filtered_ate =
      evaluation::CompareTrajectory(result.trajectory, dataset.groundtruth_trajectory);
  const evaluation::TrajectoryErrors smoothed_ate =
      evaluation::CompareTrajectory(smoothed, dataset.groundtruth_trajectory);
  std::cout << "ATE filtered " << filtered_ate.ate_translation_rmse_m << " m / "
            << filtered_ate.ate_rotation_rmse_deg << " deg, smoothed "
            << smoothed_ate.ate_translation_rmse_m << " m / " << smoothed_ate.ate_rotation_rmse_deg
            << " deg\n";
  EXPECT_LT(smoothed_ate.ate_rotation_rmse_deg, 0.75 * filtered_ate.ate_rotation_rmse_deg);
  EXPECT_LT(smoothed_ate.ate_translation_rmse_m, 0.75 * filtered_ate.ate_translation_rmse_m);
  EXPECT_LT(smoothed_ate.ate_rotation_rmse_deg, 0.1);
  std::ifstream csv(out + "/calibration_over_time.csv");
  std::string line;
  ASSERT_TRUE(std::getline(csv, line));
  EXPECT_THAT(line, ::testing::StartsWith("t_s,q_I_L_x"));
  int rows = 0;
  std::string last;
  while (std::getline(csv, line)) {
    ++rows;
    last = line;
  }
  EXPECT_EQ(rows, static_cast<int>(result.calibration_over_time.size()));
  // The stamp keeps its nanoseconds.
  const int64_t t_last = result.calibration_over_time.back().t_ns;
  EXPECT_THAT(last, ::testing::StartsWith(
                        std::to_string(t_last / 1'000'000'000) + "." +
                        std::to_string(t_last % 1'000'000'000 + 1'000'000'000).substr(1)));

  // states.csv: one row per keyframe, its last one the final state with its biases.
  std::ifstream states(out + "/states.csv");
  ASSERT_TRUE(std::getline(states, line));
  EXPECT_THAT(line, ::testing::StartsWith("t_s,p_W_I_x_m"));
  EXPECT_THAT(line, ::testing::EndsWith("b_a_z_m_s2"));
  rows = 0;
  while (std::getline(states, line)) {
    ++rows;
    last = line;
  }
  ASSERT_EQ(rows, static_cast<int>(result.states.size()));
  ASSERT_EQ(result.states.size(), result.trajectory.size());
  std::vector<double> fields;
  std::stringstream row(last.substr(last.find(',') + 1));
  for (std::string field; std::getline(row, field, ',');) fields.push_back(std::stod(field));
  ASSERT_EQ(fields.size(), 16u);
  const estimation::SlidingWindowState& final_state = result.states.back();
  EXPECT_NEAR(fields[0], final_state.p_W_I.x(), 1e-6);
  EXPECT_NEAR(fields[6], final_state.q_W_I.w(), 1e-9);
  EXPECT_NEAR(fields[10], final_state.b_g.x(), 1e-12);
  EXPECT_NEAR(fields[15], final_state.b_a.z(), 1e-12);
}

// The IMU drops out for 0.5 s at 20 s. The keyframe sweeps inside the dropout are left out, and
// the factor of the next one spans it with the unknown motion's variance (Eq. F5b). Read as the
// straight line between the two samples around it with the white noise alone, it pulled the
// time offset 3.7 ms off at a sigma of 0.28 ms; with Eq. F5b it ends 0.38 ms off at 0.30 ms.
// The offset and the extrinsic's rotation stay within three of their sigmas. (Before, the
// run stopped at the dropout: "IMU preintegration covariance is not positive definite".)
TEST_F(OnlineEstimationTest, AnImuDropoutKeepsTheSigmasHonest) {
  io::Dataset dataset = io::ReadDataset(data_->directory);
  const int64_t begin = dataset.imu.front().t_ns + SecondsToNs(20.0);
  const int64_t end = begin + SecondsToNs(0.5);
  dataset.imu.erase(
      std::remove_if(dataset.imu.begin(), dataset.imu.end(),
                     [&](const sensors::ImuSample& s) { return s.t_ns >= begin && s.t_ns < end; }),
      dataset.imu.end());
  const OnlineEstimationResult result = EstimateDatasetOnline(dataset, FullProblem());
  EXPECT_GT(result.counters.without_imu, 0);
  const sensors::Calibration& truth = data_->simulator.true_calibration();
  const sensors::Calibration& estimate = result.calibration.value;
  const io::CalibrationUncertainty& u = result.calibration.uncertainty;
  ASSERT_TRUE(u.time_offset_lidar_imu_s.sigma.has_value());
  const double offset_error_s =
      std::abs(estimate.time_offset_lidar_imu_s - truth.time_offset_lidar_imu_s);
  std::cout << result.counters.without_imu << " keyframe sweeps left out; time offset "
            << 1e3 * offset_error_s << " ms off at sigma " << 1e3 * *u.time_offset_lidar_imu_s.sigma
            << " ms\n";
  EXPECT_LT(offset_error_s, 3.0 * *u.time_offset_lidar_imu_s.sigma);
  ASSERT_TRUE(u.T_I_L.sigma_rot_deg.has_value());
  const Eigen::Vector3d rotation_error_deg =
      geometry::Log(truth.q_I_L.conjugate() * estimate.q_I_L) * kRadToDeg;
  for (int i = 0; i < 3; ++i) {
    EXPECT_LT(std::abs(rotation_error_deg(i)), 3.0 * (*u.T_I_L.sigma_rot_deg)(i)) << i;
  }
}

// The receiver states every fix's std four times too small: the window's marginalized GNSS
// rows scatter about four times their stated std, and once kMinGnssNoiseRows of them say so
// the later fixes are weighed by what they show (Eq. N2). Measured: scale 3.89 horizontal,
// 175 of 220 fixes scaled; the lever arm's sigma within 1 % of the stated run's, its value
// within 0.8 mm. Unscaled: sigma (9.0, 6.7) mm against (11.1, 9.2), y 3.2 mm from the stated
// run's.
TEST_F(OnlineEstimationTest, OptimisticGnssStdGetsTheScatterTheFixesShow) {
  const io::Dataset as_stated = io::ReadDataset(data_->directory);
  const OnlineEstimationResult stated = EstimateDatasetOnline(as_stated, FullProblem());
  const OnlineEstimationResult result =
      EstimateDatasetOnline(test::WithOptimisticGnssStd(as_stated), FullProblem());
  EXPECT_EQ(stated.calibration.residuals.at("gnss").at("noise_scale_horizontal"), 1.0);
  EXPECT_EQ(stated.calibration.residuals.at("gnss").at("noise_scale_vertical"), 1.0);
  EXPECT_EQ(stated.counters.gnss_scaled, 0);
  EXPECT_THAT(stated.warnings,
              ::testing::Not(::testing::Contains(::testing::HasSubstr("stated std"))));
  EXPECT_THAT(result.warnings, ::testing::Contains(::testing::HasSubstr("took their std scaled")));
  EXPECT_THAT(result.warnings,
              ::testing::Contains(::testing::HasSubstr("about the GNSS-inertial start")));
  const std::map<std::string, double>& gnss = result.calibration.residuals.at("gnss");
  const sensors::Calibration& truth = data_->simulator.true_calibration();
  std::cout << "GNSS noise scale " << gnss.at("noise_scale_horizontal") << ", "
            << result.counters.gnss_scaled << " of " << result.counters.gnss_accepted
            << " fixes scaled; lever arm sigma "
            << result.calibration.uncertainty.p_I_A_m.sigma.value().transpose() << " m against "
            << stated.calibration.uncertainty.p_I_A_m.sigma.value().transpose()
            << " m as stated; errors " << (result.calibration.value.p_I_A - truth.p_I_A).transpose()
            << " m against " << (stated.calibration.value.p_I_A - truth.p_I_A).transpose()
            << " m\n";
  EXPECT_EQ(gnss.at("fixes_scaled"), static_cast<double>(result.counters.gnss_scaled));
  // Every fix the window attached, from the first: the start's fit measured the scale before
  // the window's own rows could (measured 218 of the 220 accepted, the two others never attached
  // to a keyframe). Without the start's scale the first 44 took the stated std (67 horizontal
  // rows are 34 fixes, which leave the window 10 keyframes after they arrive).
  EXPECT_GE(result.counters.gnss_scaled, result.counters.gnss_accepted - 2);
  test::ExpectScaledGnssAndTheLeverArmAsStated(result.calibration, stated.calibration);
}

// The window starts from the initializer, which takes no guess: a nominal calibration off by
// 20 deg, 0.3 m and 40 ms (the bad guess) ends within the same bounds (measured:
// q_I_L 3.06 -> 0.064 deg, p_I_L x, y within 1.1 cm, offset 0.17 ms, position 0.024 m rms).
TEST_F(OnlineEstimationTest, ABadNominalGuessEndsWithinTheSameBounds) {
  io::Dataset dataset = io::ReadDataset(data_->directory);
  test::SpoilNominalGuess(&dataset.sensors);
  const OnlineEstimationResult result = EstimateDatasetOnline(dataset, FullProblem());
  ExpectOnlineGoals(ErrorsOf(result, dataset, data_->simulator.true_calibration()));
}

// The offline calibration's plausibility rule on the window's final estimate: a nominal lever
// arm 40 cm off in x, stated to 2 cm, which the drive contradicts, stops the run with the
// direction named instead of being held at the stated value (measured: moved 23 cm, 11 prior
// sigmas; the stream's information about it is 1.3 times the prior's).
TEST_F(OnlineEstimationTest, RefusesAResultFarOutsideAStatedPrior) {
  io::Dataset dataset = io::ReadDataset(data_->directory);
  test::MisstateNominalLeverArm(&dataset.sensors, 0.40, 0.02);
  try {
    EstimateDatasetOnline(dataset, FullProblem());
    FAIL() << "a lever arm far outside its stated prior was returned as a result";
  } catch (const Error& e) {
    std::cout << e.what() << "\n";
    EXPECT_THAT(e.what(), ::testing::HasSubstr("did not converge to a plausible result"));
    EXPECT_THAT(e.what(), ::testing::HasSubstr("GNSS antenna x lever arm (IMU frame) moved"));
  }
}

// A stated sigma per axis reaches the window's prior and its report: the antenna's height,
// stated to 5 mm at its true value while x and y are stated to 3 cm, is held (the drive does
// not excite it) and reported with its own 5 mm, where the window's one sigma per block
// reported 3 cm.
TEST_F(OnlineEstimationTest, ReportsAHeldDirectionWithItsOwnAxisSigma) {
  io::Dataset dataset = io::ReadDataset(data_->directory);
  dataset.sensors.nominal_calibration.p_I_A.z() = data_->simulator.true_calibration().p_I_A.z();
  io::VectorBlockInfo stated;
  stated.sigma = Eigen::Vector3d(0.03, 0.03, 0.005);
  dataset.sensors.nominal_uncertainty.p_I_A_m = stated;
  const OnlineEstimationResult result = EstimateDatasetOnline(dataset, FullProblem());
  ASSERT_TRUE(result.calibration.uncertainty.p_I_A_m.sigma.has_value());
  const Eigen::Vector3d sigma_m = *result.calibration.uncertainty.p_I_A_m.sigma;
  EXPECT_DOUBLE_EQ(sigma_m.z(), 0.005);
  EXPECT_LT(sigma_m.head<2>().maxCoeff(), 0.015);  // the drive determines x and y
  EXPECT_THAT(result.warnings, ::testing::Contains(::testing::HasSubstr(
                                   "GNSS antenna z lever arm (IMU frame): not excited")));
}

// The 30 s drive with every sweep stamped when it ends (points at negative times, as some
// drivers write them) streams to the same goals. Measured: 0.067 deg, p_I_L x, y (9.1, 4.9) mm,
// offset 0.15 ms, 2.3 cm RMS.
TEST(OnlineEstimationEndStamped, StreamsSweepsStampedAtTheirEnd) {
  const test::SimulatedUrbanDataset data(test::EndStampedUrbanDriveOptions(30.0),
                                         "urban_30s_end_stamped");
  const io::Dataset dataset = io::ReadDataset(data.directory);
  ASSERT_LT(dataset.LoadSweep(0).cloud.time_s.maxCoeff(), 0.0);
  const OnlineEstimationResult result = EstimateDatasetOnline(dataset, FullProblem());
  EXPECT_GT(result.counters.updates, 250);
  ExpectOnlineGoals(ErrorsOf(result, dataset, data.simulator.true_calibration()));
}

// An IMU log that starts after the first sweeps: the initializer's first keyframe is a later
// sweep (of every initializer_sweep_stride-th), and streaming starts with the sweep after it,
// each one a keyframe a sweep period after the last, none dropped as late.
TEST_F(OnlineEstimationTest, StartsStreamingAfterTheInitialKeyframesSweep) {
  io::Dataset dataset = io::ReadDataset(data_->directory);
  const int64_t imu_start_ns = dataset.lidar_sweeps[4].t_ns;
  dataset.imu.erase(
      dataset.imu.begin(),
      std::lower_bound(dataset.imu.begin(), dataset.imu.end(), imu_start_ns,
                       [](const sensors::ImuSample& s, int64_t t) { return s.t_ns < t; }));
  const OnlineEstimationResult result = EstimateDatasetOnline(dataset, FullProblem());
  EXPECT_EQ(result.counters.late, 0);
  ASSERT_GT(result.trajectory.size(), 2u);
  EXPECT_GT(result.trajectory.front().t_ns, imu_start_ns);
  const int64_t period_ns = dataset.lidar_sweeps[5].t_ns - dataset.lidar_sweeps[4].t_ns;
  EXPECT_NEAR(static_cast<double>(result.trajectory[1].t_ns - result.trajectory[0].t_ns),
              static_cast<double>(period_ns), 0.1 * static_cast<double>(period_ns));
}

// The thread count changes nothing: trajectory, calibration and sigma are the same to the last
// digit at 1 and 2 threads (docs/calibration.md, "Reproducibility and threads").
TEST_F(OnlineEstimationTest, OneAndTwoThreadsGiveTheSameResult) {
  const io::Dataset dataset = io::ReadDataset(data_->directory);
  io::Problem problem = FullProblem();
  problem.solver.num_threads = 1;
  const OnlineEstimationResult one = EstimateDatasetOnline(dataset, problem);
  problem.solver.num_threads = 2;
  const OnlineEstimationResult two = EstimateDatasetOnline(dataset, problem);
  ASSERT_EQ(one.trajectory.size(), two.trajectory.size());
  for (size_t i = 0; i < one.trajectory.size(); ++i) {
    ASSERT_EQ(one.trajectory[i].T_W_I.p, two.trajectory[i].T_W_I.p) << "keyframe " << i;
    ASSERT_EQ(one.trajectory[i].T_W_I.q.coeffs(), two.trajectory[i].T_W_I.q.coeffs()) << i;
  }
  EXPECT_EQ(io::CalibrationYamlText(one.calibration), io::CalibrationYamlText(two.calibration));
}

// A missing sweep file among the initializer's (read on num_threads threads) fails with its
// path before anything is estimated; the streamed sweeps: sweep_reader_test.cc.
TEST_F(OnlineEstimationTest, AMissingSweepFileFailsWithItsPath) {
  io::Dataset dataset = io::ReadDataset(data_->directory);
  ASSERT_GT(dataset.lidar_sweeps.size(), 250u);
  dataset.lidar_sweeps[40].file = "missing.ply";
  dataset.lidar_sweeps[200].file = "also_missing.ply";
  io::Problem problem = FullProblem();
  problem.solver.num_threads = 2;
  try {
    EstimateDatasetOnline(dataset, problem);
    FAIL() << "the missing sweep was not missed";
  } catch (const ParseError& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("missing.ply"));  // the first, as read in order
    EXPECT_THAT(e.what(), ::testing::Not(::testing::HasSubstr("also_missing.ply")));
    EXPECT_THAT(e.what(), ::testing::HasSubstr("sweep file not found"));
  }
}

TEST_F(OnlineEstimationTest, RefusesWhatItCannotDo) {
  const io::Dataset full = io::ReadDataset(data_->directory);
  io::Dataset no_wheel = full;
  no_wheel.wheel.clear();
  try {
    EstimateDatasetOnline(no_wheel, FullProblem());
    FAIL() << "a problem with wheels on a dataset without them was accepted";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("wheel"));
  }
  // Without the LiDAR the start is placed on the GNSS track (online_estimation_without_lidar
  // _test.cc): without GNSS either nothing starts the window.
  io::Problem no_lidar = FullProblem();
  no_lidar.sensors.lidar = false;
  no_lidar.sensors.gnss = false;
  no_lidar.calibration.p_I_A_m.mode = io::BlockMode::kFixed;
  try {
    EstimateDatasetOnline(full, no_lidar);
    FAIL() << "a problem with neither the LiDAR nor GNSS was accepted";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("without the LiDAR needs GNSS"));
  }
  io::Problem shared = FullProblem();
  shared.calibration.wheel_radius_shared = true;
  EXPECT_THROW(EstimateDatasetOnline(full, shared), Error);
  OnlineEstimationOptions options;
  options.initialization_duration_s = 0.0;
  EXPECT_THROW(EstimateDatasetOnline(full, FullProblem(), options), Error);
  for (const auto& [stretches, significance] :
       std::vector<std::pair<int, double>>{{2, 0.001}, {-1, 0.001}, {32, 0.0}, {32, 1.0}}) {
    OnlineEstimationOptions scatter;
    scatter.scatter_stretches = stretches;
    scatter.scatter_significance = significance;
    try {
      EstimateDatasetOnline(full, FullProblem(), scatter);
      ADD_FAILURE() << stretches << " stretches at " << significance << " were accepted";
    } catch (const Error& e) {
      EXPECT_THAT(e.what(), ::testing::HasSubstr("scatter_stretches must be 0"));
    }
  }
}

// A 30 s highway drive (seed 3, the offline test's, no turns, traffic around the car) with
// problems/highway.yaml streams through the window: the initializer's rotation and offset fall
// back to the nominal values, its LiDAR odometry does not follow the road, and the window
// starts from GNSS and the IMU with the calibration the offline batch finds on the first 15 s,
// each step named in a warning. Refused before: "the initializer could not start the window".
// From the nominal values instead (3.5 deg off) the window ended with the LiDAR pitch 0.69 deg
// off at a stated 0.11 deg on this drive (with its earlier beams, -25 to 15 deg, and the Huber
// loss), 3.8 deg off on the same seed from autocal_simulate,
// and 2.5 and 8.3 deg off on seeds 4 and 5 (docs/sliding_window.md).
TEST(OnlineEstimationHighway, StartsFromTheBatchWhereTheLidarOdometryDoesNotFollow) {
  const test::SimulatedUrbanDataset data(test::HighwayDriveOptions(30.0, 3), "highway_30s");
  const io::Dataset dataset = io::ReadDataset(data.directory);
  const io::Problem problem = test::ShippedProblem("highway.yaml");
  OnlineEstimationOptions options;
  options.initialization_duration_s = 15.0;
  const OnlineEstimationResult result = EstimateDatasetOnline(dataset, problem, options);
  for (const std::string& w : result.warnings) std::cout << "warning: " << w << "\n";
  EXPECT_THAT(result.warnings,
              ::testing::Contains(::testing::HasSubstr("initialization: too little rotation")));
  EXPECT_THAT(result.warnings,
              ::testing::Contains(::testing::HasSubstr(
                  "LiDAR odometry could not be aligned to the GNSS fixes of the first 15 s")));
  EXPECT_THAT(
      result.warnings,
      ::testing::Contains(::testing::HasSubstr("its calibration from the offline calibration")));
  // The batch searched the nominal rotation (3.5 deg off) and says where it started.
  EXPECT_THAT(result.warnings,
              ::testing::Contains(::testing::HasSubstr(
                  "the start's offline calibration: the LiDAR rotation's nominal value")));

  // The start is the batch's result on the initializer's sweeps, those stamped before 15 s
  // from the first one (on one thread).
  io::Problem one_thread = problem;
  one_thread.solver.num_threads = 1;
  const int64_t end_ns =
      dataset.lidar_sweeps.front().t_ns + SecondsToNs(options.initialization_duration_s);
  const sensors::Calibration batch =
      CalibrateDataset(io::DatasetUntil(dataset, end_ns - 1), one_thread).calibration.value;
  EXPECT_TRUE(result.initial.q_I_L.isApprox(batch.q_I_L, 1e-12));
  EXPECT_EQ(result.initial.time_offset_lidar_imu_s, batch.time_offset_lidar_imu_s);
  EXPECT_TRUE(result.initial.q_I_V.isApprox(batch.q_I_V, 1e-12));

  // Every LiDAR rotation axis within three of its stated sigmas (the right perturbation at
  // the estimate), the trajectory within 5 cm and 1 deg RMS. Measured: pitch and yaw -0.22
  // and 0.22 deg at sigma 0.28 and 0.13 deg, the roll held at its prior (sigma 0.49 deg after
  // the solve); trajectory 3.0 cm, 0.38 deg.
  const sensors::Calibration& truth = data.simulator.true_calibration();
  const Eigen::Vector3d delta_deg =
      geometry::Log(result.calibration.value.q_I_L.conjugate() * truth.q_I_L) * kRadToDeg;
  const Eigen::Vector3d sigma_deg = *result.calibration.uncertainty.T_I_L.sigma_rot_deg;
  const evaluation::TrajectoryErrors ate =
      evaluation::CompareTrajectory(result.trajectory, dataset.groundtruth_trajectory);
  std::cout << "LiDAR rotation error " << delta_deg.transpose() << " deg at sigma "
            << sigma_deg.transpose() << " deg; trajectory " << ate.ate_translation_rmse_m << " m / "
            << ate.ate_rotation_rmse_deg << " deg RMS\n";
  for (int a = 0; a < 3; ++a) EXPECT_LT(std::abs(delta_deg(a)), 3.0 * sigma_deg(a)) << a;
  EXPECT_LT(ate.ate_translation_rmse_m, 0.05);
  EXPECT_LT(ate.ate_rotation_rmse_deg, 1.0);

  // Without GNSS nothing would tell a failed odometry: the initializer's problems refuse.
  try {
    EstimateDatasetOnline(dataset, test::ShippedProblem("lidar_imu.yaml"), options);
    ADD_FAILURE() << "a highway start without GNSS was not refused";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("could not start the window"));
  }
}

}  // namespace
}  // namespace pipeline
}  // namespace autocal
