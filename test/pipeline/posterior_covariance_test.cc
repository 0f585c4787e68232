// pipeline::PosteriorCovariance: the covariance from the completed Hessian (docs/calibration.md,
// Eq. C5), and Gauss-Newton's with a warning where the completed matrix is not positive
// definite.

#include <ceres/ceres.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "autocal/estimation/calibration_observability.h"
#include "autocal/factors/loss.h"
#include "pipeline/calibration_steps.h"

namespace autocal {
namespace pipeline {
namespace {

// r = a (x - x0)^2 - m on the left wheel radius x: J = 2 a (x - x0), d2r = 2 a.
struct Parabola {
  double a, x0, m;
  template <typename T>
  bool operator()(const T* x, T* r) const {
    r[0] = T(a) * (x[0] - T(x0)) * (x[0] - T(x0)) - T(m);
    return true;
  }
};

struct OneBlockProblem {
  sensors::Calibration calibration;
  std::vector<estimation::EstimatedBlock> blocks;
  ceres::Problem problem;

  // At x = 0.33 with a = 10, x0 = 0.23: J = 2, J^T J = 4, r = 0.1 - m, r d2r = 20 (0.1 - m);
  // a prior of sigma 1 adds 1.
  explicit OneBlockProblem(double m) {
    calibration.wheel_radius_left_m = 0.33;
    blocks = {estimation::BlockOf(sensors::CalibrationBlockId::kWheelRadiusLeft, &calibration)};
    blocks[0].prior = Eigen::VectorXd::Constant(1, 0.33);
    blocks[0].prior_sigma = Eigen::VectorXd::Ones(1);
    estimation::AddBlockPriors(blocks, factors::LossOptions(), &problem);
    problem.AddResidualBlock(
        new ceres::AutoDiffCostFunction<Parabola, 1, 1>(new Parabola{10.0, 0.23, m}), nullptr,
        &calibration.wheel_radius_left_m);
  }
};

TEST(PosteriorCovariance, TakesTheCompletedHessian) {
  OneBlockProblem one(0.05);  // r = 0.05: H = 4 + 1 + 20 * 0.05 = 6
  std::vector<std::string> warnings;
  const estimation::BlockCovariance covariance =
      PosteriorCovariance(one.blocks, &one.problem, 1, &warnings);
  ASSERT_TRUE(covariance.ok);
  EXPECT_NEAR(covariance.matrix(0, 0), 1.0 / 6.0, 1e-8);
  EXPECT_TRUE(warnings.empty());
}

TEST(PosteriorCovariance, FallsBackToGaussNewtonWhereTheCostCurvesDown) {
  OneBlockProblem one(1.1);  // r = -1: H = 4 + 1 - 20 < 0, Gauss-Newton's 5
  std::vector<std::string> warnings;
  const estimation::BlockCovariance covariance =
      PosteriorCovariance(one.blocks, &one.problem, 1, &warnings);
  ASSERT_TRUE(covariance.ok);
  EXPECT_NEAR(covariance.matrix(0, 0), 1.0 / 5.0, 1e-12);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_THAT(warnings[0], ::testing::HasSubstr("not positive definite"));
}

}  // namespace
}  // namespace pipeline
}  // namespace autocal
