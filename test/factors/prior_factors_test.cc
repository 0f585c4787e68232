#include "autocal/factors/prior_factors.h"

#include <ceres/ceres.h>
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/geometry/manifolds.h"
#include "factors/factor_test_utils.h"

namespace autocal {
namespace factors {
namespace {

Eigen::Vector3d RandomVector(std::mt19937* rng, double scale) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  return Eigen::Vector3d(u(*rng), u(*rng), u(*rng)) * scale;
}

// A random symmetric positive-definite covariance with condition number up to ~100.
Eigen::MatrixXd RandomCovariance(std::mt19937* rng, int n) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::MatrixXd a(n, n);
  for (int i = 0; i < n * n; ++i) a.data()[i] = u(*rng);
  return a * a.transpose() * 0.01 + 0.001 * Eigen::MatrixXd::Identity(n, n);
}

TEST(SqrtInformation, WhitensTheCovariance) {
  std::mt19937 rng(1);
  for (int n : {1, 3, 15}) {
    const Eigen::MatrixXd cov = RandomCovariance(&rng, n);
    const Eigen::MatrixXd U = SqrtInformationFromCovariance(cov);
    EXPECT_LT((U * cov * U.transpose() - Eigen::MatrixXd::Identity(n, n)).norm(), 1e-9)
        << "n = " << n;
  }
  const Eigen::MatrixXd U = SqrtInformationFromSigmas(Eigen::Vector3d(0.1, 2.0, 0.5));
  EXPECT_DOUBLE_EQ(U(0, 0), 10.0);
  EXPECT_DOUBLE_EQ(U(1, 1), 0.5);
  EXPECT_THROW(SqrtInformationFromSigmas(Eigen::Vector3d(0.1, 0.0, 0.5)), Error);
  EXPECT_THROW(SqrtInformationFromCovariance(-Eigen::MatrixXd::Identity(3, 3)), Error);
  Eigen::MatrixXd asymmetric = Eigen::MatrixXd::Identity(2, 2);
  asymmetric(0, 1) = 0.5;
  EXPECT_THROW(SqrtInformationFromCovariance(asymmetric), Error);
}

TEST(QuaternionPriorFactor, ZeroAtThePriorAndJacobiansCheck) {
  const geometry::RightQuaternionManifold manifold;
  std::mt19937 rng(2);
  for (int trial = 0; trial < 20; ++trial) {
    const Eigen::Quaterniond q0 = Eigen::Quaterniond::UnitRandom();
    const Eigen::Matrix3d U = SqrtInformationFromCovariance(RandomCovariance(&rng, 3));
    const QuaternionPriorFactor factor(q0, U);
    Eigen::Quaterniond q = q0;
    Eigen::Vector3d residual;
    std::vector<double*> blocks = {q.coeffs().data()};
    ASSERT_TRUE(factor.Evaluate(blocks.data(), residual.data(), nullptr));
    EXPECT_LT(residual.norm(), 1e-12) << "trial " << trial;
    // A right perturbation d gives the residual U d exactly (Eq. F40).
    const Eigen::Vector3d d = RandomVector(&rng, 0.5);
    q = q0 * geometry::Exp(d);
    ASSERT_TRUE(factor.Evaluate(blocks.data(), residual.data(), nullptr));
    EXPECT_LT((residual - U * d).norm(), 1e-9 * (U * d).norm()) << "trial " << trial;
    q = q0 * geometry::Exp(RandomVector(&rng, 1.5));
    test::ExpectGradientCheckPasses(factor, {&manifold}, blocks, 1e-6,
                                    "trial " + std::to_string(trial));
  }
}

TEST(VectorPriorFactor, WhitensTheDeviationAndJacobiansCheck) {
  std::mt19937 rng(3);
  for (int n : {1, 3, 6}) {
    Eigen::VectorXd x0(n), x(n);
    for (int i = 0; i < n; ++i) {
      x0(i) = RandomVector(&rng, 2.0).x();
      x(i) = RandomVector(&rng, 2.0).x();
    }
    const Eigen::MatrixXd U = SqrtInformationFromCovariance(RandomCovariance(&rng, n));
    const VectorPriorFactor factor(x0, U);
    Eigen::VectorXd residual(n);
    std::vector<double*> blocks = {x.data()};
    ASSERT_TRUE(factor.Evaluate(blocks.data(), residual.data(), nullptr));
    EXPECT_LT((residual - U * (x - x0)).norm(), 1e-12) << "n = " << n;
    test::ExpectGradientCheckPasses(factor, {nullptr}, blocks, 1e-6, "n = " + std::to_string(n));
  }
  EXPECT_THROW(VectorPriorFactor(Eigen::Vector3d::Zero(), Eigen::MatrixXd::Identity(2, 2)), Error);
}

TEST(StatePriorFactor, ZeroAtThePriorAndJacobiansCheck) {
  const geometry::RightQuaternionManifold manifold;
  std::mt19937 rng(4);
  for (int trial = 0; trial < 10; ++trial) {
    StatePrior prior;
    prior.state.q_W_I = Eigen::Quaterniond::UnitRandom();
    prior.state.p_W_I = RandomVector(&rng, 50.0);
    prior.state.v_W_I = RandomVector(&rng, 10.0);
    prior.b_g = RandomVector(&rng, 0.01);
    prior.b_a = RandomVector(&rng, 0.1);
    prior.sqrt_information = SqrtInformationFromCovariance(RandomCovariance(&rng, 15));
    const StatePriorFactor factor(prior);
    Eigen::Quaterniond q = prior.state.q_W_I;
    Eigen::Vector3d p = prior.state.p_W_I, v = prior.state.v_W_I, b_g = prior.b_g, b_a = prior.b_a;
    std::vector<double*> blocks = {q.coeffs().data(), p.data(), v.data(), b_g.data(), b_a.data()};
    Eigen::Matrix<double, 15, 1> residual;
    ASSERT_TRUE(factor.Evaluate(blocks.data(), residual.data(), nullptr));
    EXPECT_LT(residual.norm(), 1e-12) << "trial " << trial;
    q = q * geometry::Exp(RandomVector(&rng, 1.0));
    p += RandomVector(&rng, 1.0);
    v += RandomVector(&rng, 1.0);
    b_g += RandomVector(&rng, 0.01);
    b_a += RandomVector(&rng, 0.1);
    test::ExpectGradientCheckPasses(factor, {&manifold, nullptr, nullptr, nullptr, nullptr}, blocks,
                                    1e-6, "trial " + std::to_string(trial));
  }
}

// A prior whose rotation is no rotation (a zero quaternion, which normalizing leaves zero, or a
// NaN) is refused when made, not evaluated to NaN in a solve.
TEST(StatePriorFactor, RefusesAPriorWithoutARotation) {
  StatePrior prior;
  prior.sqrt_information = Eigen::MatrixXd::Identity(15, 15);
  prior.state.q_W_I.coeffs().setZero();
  EXPECT_THROW(StatePriorFactor{prior}, Error);
  prior.state.q_W_I.coeffs() << 0.0, 0.0, std::nan(""), 1.0;
  EXPECT_THROW(StatePriorFactor{prior}, Error);
  prior.state.q_W_I.coeffs() << 0.0, 0.0, 0.0, 2.0;  // not unit, still a rotation
  EXPECT_NO_THROW(StatePriorFactor{prior});
}

// A prior alone pulls a quaternion block back to its value through the manifold.
TEST(QuaternionPriorFactor, PullsTheBlockToThePriorInASolve) {
  const Eigen::Quaterniond q0 = Eigen::Quaterniond::UnitRandom();
  Eigen::Quaterniond q = q0 * geometry::Exp(Eigen::Vector3d(1.0, -0.8, 0.6));
  ceres::Problem problem;
  problem.AddResidualBlock(new QuaternionPriorFactor(q0, Eigen::Matrix3d::Identity() * 100.0),
                           nullptr, q.coeffs().data());
  problem.SetManifold(q.coeffs().data(), new geometry::RightQuaternionManifold);
  ceres::Solver::Options options;
  // Converge to rounding, not to Ceres' default tolerances.
  options.function_tolerance = 1e-15;
  options.parameter_tolerance = 1e-15;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  EXPECT_LT(geometry::AngularDistance(q, q0), 1e-9) << summary.BriefReport();
}

}  // namespace
}  // namespace factors
}  // namespace autocal
