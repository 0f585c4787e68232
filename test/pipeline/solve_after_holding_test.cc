// pipeline::SolveAgainAfterHolding (docs/calibration.md, Eq. C3): the held directions are pinned
// for its solve only. A held value is the nominal one, known to its prior's sigma; the later
// test of the fixed blocks (Eq. C7) counts that error, as Eq. C2 does for the kept directions.

#include <ceres/ceres.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "autocal/estimation/calibration_observability.h"
#include "autocal/factors/loss.h"
#include "pipeline/calibration_steps.h"

namespace autocal {
namespace pipeline {
namespace {

// 50 (f + 0.1 u - m): the fixed right radius f and the estimated left radius u, as one row.
struct CoupledRow {
  double m;
  template <typename T>
  bool operator()(const T* u, const T* f, T* r) const {
    r[0] = T(50.0) * (f[0] + T(0.1) * u[0] - T(m));
    return true;
  }
};

// u is 1.2 m off its nominal 0.33 and barely informed (sigma 0.17 after the solve, prior 0.3):
// held. f is fixed at its true value. Freed under a prior of 0.3 with u free under its own,
// the data move f by 0.118 at sigma 0.0358, 3.3 sigma, f + 0.1 u being all the row sees; with
// u pinned, sigma 0.0200 made it 6.0 sigma, beyond the 5 of a warning.
TEST(SolveAgainAfterHolding, LeavesNoPinForTheFixedBlocksTest) {
  sensors::Calibration calibration;
  calibration.wheel_radius_left_m = 0.33;
  calibration.wheel_radius_right_m = 0.33;
  std::vector<estimation::EstimatedBlock> blocks = {
      estimation::BlockOf(sensors::CalibrationBlockId::kWheelRadiusLeft, &calibration)};
  blocks[0].prior = Eigen::VectorXd::Constant(1, 0.33);
  blocks[0].prior_sigma = Eigen::VectorXd::Constant(1, 0.3);
  blocks[0].max_observable_sigma = 0.02;
  std::vector<estimation::EstimatedBlock> fixed = {
      estimation::BlockOf(sensors::CalibrationBlockId::kWheelRadiusRight, &calibration)};
  fixed[0].prior = Eigen::VectorXd::Constant(1, 0.33);
  fixed[0].prior_sigma = Eigen::VectorXd::Constant(1, 0.3);
  fixed[0].max_observable_sigma = 0.02;

  ceres::Problem p;
  estimation::AddBlockPriors(blocks, factors::LossOptions(), &p);
  p.AddResidualBlock(new ceres::AutoDiffCostFunction<CoupledRow, 1, 1, 1>(
                         new CoupledRow{0.33 + 0.1 * (0.33 + 1.2)}),
                     nullptr, &calibration.wheel_radius_left_m, &calibration.wheel_radius_right_m);
  p.SetParameterBlockConstant(&calibration.wheel_radius_right_m);
  ceres::Solver::Options options;
  options.function_tolerance = options.gradient_tolerance = options.parameter_tolerance = 1e-15;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &p, &summary);
  const sensors::Calibration solved = calibration;
  const estimation::BlockCovariance covariance = estimation::ComputeBlockCovariance(blocks, &p);
  ASSERT_TRUE(covariance.ok);
  const estimation::BlockObservability observability =
      estimation::HoldUnobservableDirections(blocks, covariance);
  ASSERT_THAT(observability.held[0], ::testing::ElementsAre(true));

  const int residual_blocks = p.NumResidualBlocks();
  OfflineCalibrationResult result;
  SolveAgainAfterHolding(io::Problem(), blocks, observability, solved, &calibration, &p, &result);
  EXPECT_EQ(calibration.wheel_radius_left_m, 0.33);
  EXPECT_EQ(p.NumResidualBlocks(), residual_blocks);
  EXPECT_THAT(estimation::FixedDirectionsTheDataMove(fixed, &p, 1, 5.0), ::testing::IsEmpty());
  EXPECT_THAT(estimation::FixedDirectionsTheDataMove(fixed, &p, 1, 3.0),
              ::testing::ElementsAre(
                  ::testing::AllOf(::testing::Field(&estimation::FixedDirectionMove::step,
                                                    ::testing::DoubleNear(0.1184, 2e-4)),
                                   ::testing::Field(&estimation::FixedDirectionMove::sigma,
                                                    ::testing::DoubleNear(0.0358, 2e-4)))));
}

}  // namespace
}  // namespace pipeline
}  // namespace autocal
