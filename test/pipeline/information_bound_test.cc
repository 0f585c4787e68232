// The Cramer-Rao bound of the offline calibration on a simulated log (docs/evaluation.md,
// "Information bound"): computed at the truth on the final problem, it changes nothing of the
// result, and an efficient solve's sigma is the bound.
#include "autocal/evaluation/information_bound.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <iostream>
#include <string>

#include "autocal/common/units.h"
#include "autocal/geometry/so3.h"
#include "autocal/pipeline/offline_calibration.h"
#include "autocal/pipeline/report_html.h"
#include "autocal/sensors/calibration_blocks.h"
#include "pipeline/simulated_urban_dataset.h"
#include "support/skid_steer_options.h"

namespace autocal {
namespace pipeline {
namespace {

using test::ShippedProblem;

// The 34 s urban drive, simulated once per test program and build.
const test::SimulatedUrbanDataset& Drive() {
  static const test::SimulatedUrbanDataset* const drive =
      new test::SimulatedUrbanDataset(34.0, "urban_34s");
  return *drive;
}

// sigma / bound per direction the data inform (bound below half the prior's sigma).
void ExpectSigmaAtTheBound(const OfflineCalibrationResult& result, double low, double high) {
  const estimation::CalibrationPosterior& posterior = result.posterior;
  ASSERT_TRUE(posterior.covariance.ok);
  int informed = 0;
  for (size_t b = 0; b < posterior.blocks.size(); ++b) {
    const estimation::EstimatedBlock& block = posterior.blocks[b];
    for (int i = 0; i < block.size; ++i) {
      const int row = posterior.covariance.offsets[b] + i;
      const double sigma = std::sqrt(posterior.covariance.matrix(row, row));
      const double bound = std::sqrt(result.bound->matrix(row, row));
      if (!(bound < 0.5 * block.prior_sigma(i))) continue;
      ++informed;
      const std::string& name = block.direction_names[static_cast<size_t>(i)];
      std::cout << name << ": sigma / bound " << sigma / bound << "\n";
      EXPECT_GT(sigma / bound, low) << name;
      EXPECT_LT(sigma / bound, high) << name;
    }
  }
  EXPECT_GE(informed, 5);
}

// The error budget at the truth: every sensor a source, the spreads' squares the variance of
// the solver's own J^T J (the budget's covariance; the bound scales the LiDAR's information by
// its loss's sandwich, Eq. C6, and lies below it), and the shares' sum the solve's error to first
// order: within a quarter of the bound (measured: 0.14 of it at most, the track width; the time
// offset 0.12).
void ExpectTheBudgetSplitsTheError(const OfflineCalibrationResult& result) {
  ASSERT_TRUE(result.error_budget.has_value());
  const estimation::ErrorBudget& budget = *result.error_budget;
  EXPECT_THAT(budget.sources, ::testing::ElementsAre("lidar", "gnss", "imu", "wheel", "priors"));
  EXPECT_EQ(budget.covariance.offsets, result.bound->offsets);
  const Eigen::VectorXd variance = budget.spread.cwiseAbs2().rowwise().sum();
  // Equal but for rounding through H^-1 (measured: 7e-9 relative at most).
  const Eigen::ArrayXd ratio = variance.array() / budget.covariance.matrix.diagonal().array();
  EXPECT_LT((ratio - 1.0).abs().maxCoeff(), 1e-6) << ratio.transpose();
  const Eigen::ArrayXd scaled =
      result.bound->matrix.diagonal().array() / budget.covariance.matrix.diagonal().array();
  EXPECT_LE(scaled.maxCoeff(), 1.0 + 1e-9) << scaled.transpose();
  const Eigen::VectorXd first_order = budget.share.rowwise().sum();
  for (Eigen::Index row = 0; row < first_order.size(); ++row) {
    const double bound = std::sqrt(result.bound->matrix(row, row));
    EXPECT_NEAR(first_order(row), result.error_at_bound(row), 0.25 * bound) << row;
  }
}

TEST(InformationBound, ChangesNothingAndMatchesTheSolvesSigma) {
  const io::Dataset dataset = io::ReadDataset(Drive().directory);
  const io::Problem problem = ShippedProblem("urban_full.yaml");
  const OfflineCalibrationResult plain = CalibrateDataset(dataset, problem);
  OfflineCalibrationOptions options;
  options.set_to_truth = evaluation::TruthSetter(dataset);
  ASSERT_TRUE(options.set_to_truth);
  const OfflineCalibrationResult bounded = CalibrateDataset(dataset, problem, options);
  EXPECT_FALSE(plain.bound.has_value());
  ASSERT_TRUE(bounded.bound.has_value());

  // The states and the calibration come back exactly: the same result.
  for (const sensors::CalibrationBlockInfo& info : sensors::CalibrationBlocks()) {
    const double* a = info.const_values(plain.calibration.value);
    const double* b = info.const_values(bounded.calibration.value);
    for (int k = 0; k < info.ambient_size; ++k) EXPECT_EQ(a[k], b[k]) << info.key;
  }
  ASSERT_EQ(plain.trajectory.size(), bounded.trajectory.size());
  for (size_t k = 0; k < plain.trajectory.size(); ++k) {
    EXPECT_EQ(plain.trajectory[k].T_W_I.p, bounded.trajectory[k].T_W_I.p) << k;
  }
  // Laid out as the posterior, whose blocks it bounds.
  EXPECT_EQ(bounded.bound->offsets, bounded.posterior.covariance.offsets);
  // At a solve this close to the truth the information hardly moves: sigma = bound within
  // 10 % (measured: 1.000 within 0.3 %, the track width 1.06).
  ExpectSigmaAtTheBound(bounded, 0.9, 1.1);
  // Each direction's error at the solve, laid out as the bound: truth - estimate, a rotation's
  // as Log(q_estimate^-1 q_truth).
  const sensors::Calibration& truth = Drive().simulator.true_calibration();
  const sensors::Calibration& solved = bounded.posterior.solved;
  ASSERT_EQ(bounded.error_at_bound.size(), bounded.bound->matrix.rows());
  int checked = 0;
  for (size_t b = 0; b < bounded.posterior.blocks.size(); ++b) {
    const estimation::EstimatedBlock& block = bounded.posterior.blocks[b];
    const Eigen::VectorXd error =
        bounded.error_at_bound.segment(bounded.bound->offsets[b], block.size);
    if (block.id == sensors::CalibrationBlockId::kLidarRotation) {
      ++checked;
      EXPECT_TRUE(error.isApprox(geometry::Log(solved.q_I_L.conjugate() * truth.q_I_L), 1e-12));
    }
    if (block.id == sensors::CalibrationBlockId::kTimeOffset) {
      ++checked;
      EXPECT_EQ(error(0), truth.time_offset_lidar_imu_s - solved.time_offset_lidar_imu_s);
    }
  }
  EXPECT_EQ(checked, 2);
  ExpectTheBudgetSplitsTheError(bounded);
  const std::string html = CalibrationReportHtml(bounded);
  EXPECT_NE(html.find("Against the Cramér–Rao bound"), std::string::npos);
  EXPECT_NE(html.find("error / bound"), std::string::npos);
  EXPECT_NE(html.find("Where the error comes from"), std::string::npos);
  EXPECT_EQ(CalibrationReportHtml(plain).find("Cramér–Rao"), std::string::npos);
}

// The calibration of `dataset` by the shipped problem `problem`, with its bound.
OfflineCalibrationResult CalibrateWithBound(const io::Dataset& dataset, const char* problem) {
  OfflineCalibrationOptions options;
  options.set_to_truth = evaluation::TruthSetter(dataset);
  return CalibrateDataset(dataset, ShippedProblem(problem), options);
}

TEST(InformationBound, BoundsTheRunWithoutTheLidar) {
  const OfflineCalibrationResult result =
      CalibrateWithBound(io::ReadDataset(Drive().directory), "imu_wheel_gnss.yaml");
  ASSERT_TRUE(result.bound.has_value());
  ExpectSigmaAtTheBound(result, 0.9, 1.1);
}

// The slow skid steer with the real robot's vibration: along the split between the IMU's yaw
// and the mount's, the IMU rows' derivative is the velocities' own noise, which Gauss-Newton
// counted as information (sigma / bound 0.68 on this drive). With the exact Hessian
// (docs/calibration.md, Eq. C5) the mount yaw's sigma is its bound (measured 0.92), the other
// directions unchanged.
TEST(InformationBound, TheSlowSkidSteersMountYawSigmaMeetsItsBound) {
  const test::SimulatedUrbanDataset data(test::VibratingSkidSteerOdometryOptions(120.0, 7),
                                         "skid_steer_bound");
  const OfflineCalibrationResult result =
      CalibrateWithBound(io::ReadDataset(data.directory), "skid_steer_imu_odometry_gnss.yaml");
  ASSERT_TRUE(result.bound.has_value());
  ExpectSigmaAtTheBound(result, 0.9, 1.1);
  int found = 0;
  for (size_t b = 0; b < result.posterior.blocks.size(); ++b) {
    const estimation::EstimatedBlock& block = result.posterior.blocks[b];
    if (block.id != sensors::CalibrationBlockId::kVehicleRotation) continue;
    ++found;
    const int row = result.posterior.covariance.offsets[b] + 2;  // about the vehicle's z
    const double sigma = std::sqrt(result.posterior.covariance.matrix(row, row));
    const double bound = std::sqrt(result.bound->matrix(row, row));
    std::cout << "mount yaw: sigma " << sigma * kRadToDeg << " deg, bound " << bound * kRadToDeg
              << " deg, error " << result.error_at_bound(row) * kRadToDeg << " deg\n";
    EXPECT_GT(sigma / bound, 0.8);
    EXPECT_LT(sigma / bound, 1.25);
  }
  EXPECT_EQ(found, 1);
}

}  // namespace
}  // namespace pipeline
}  // namespace autocal
