#include "autocal/factors/planar_rotation_factor.h"

#include <ceres/ceres.h>
#include <ceres/gradient_checker.h>
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/geometry/manifolds.h"
#include "factors/factor_test_utils.h"

namespace autocal {
namespace factors {
namespace {

TEST(PlanarRotationFactor, ResidualVanishesForATurnAboutTheVehicleUpAxis) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    Eigen::Quaterniond q_I_V = Eigen::Quaterniond::UnitRandom();
    Eigen::Vector3d b_g(u(rng), u(rng), u(rng));
    b_g *= 0.01;
    const double yaw_rate = u(rng);
    PlanarRotationMeasurement m;
    m.gyro_rad_s = q_I_V * Eigen::Vector3d(0.0, 0.0, yaw_rate) + b_g;
    m.sigma_rad_s = 0.05;
    const PlanarRotationFactor factor(m);
    Eigen::Vector2d residual;
    std::vector<double*> blocks = {b_g.data(), q_I_V.coeffs().data()};
    ASSERT_TRUE(factor.Evaluate(blocks.data(), residual.data(), nullptr));
    EXPECT_LT(residual.norm(), 1e-12) << trial;
    // A pitch rate of one sigma (about V's y axis) is a unit second row.
    m.gyro_rad_s += q_I_V * Eigen::Vector3d(0.0, 0.05, 0.0);
    ASSERT_TRUE(PlanarRotationFactor(m).Evaluate(blocks.data(), residual.data(), nullptr));
    EXPECT_NEAR(residual.y(), 1.0, 1e-12);
    EXPECT_NEAR(residual.x(), 0.0, 1e-12);
  }
}

// A mount tilted by d about V's x axis shows the yaw rate w in the pitch-rate row as -d w:
// first order in the tilt.
TEST(PlanarRotationFactor, ATiltedMountShowsTheYawRateToFirstOrder) {
  Eigen::Quaterniond q_I_V = Eigen::Quaterniond::Identity();
  Eigen::Vector3d b_g = Eigen::Vector3d::Zero();
  const double d = 0.01, w = 0.5;
  PlanarRotationMeasurement m;
  m.gyro_rad_s = Eigen::AngleAxisd(d, Eigen::Vector3d::UnitX()) * Eigen::Vector3d(0, 0, w);
  m.sigma_rad_s = 1.0;
  Eigen::Vector2d residual;
  std::vector<double*> blocks = {b_g.data(), q_I_V.coeffs().data()};
  ASSERT_TRUE(PlanarRotationFactor(m).Evaluate(blocks.data(), residual.data(), nullptr));
  EXPECT_NEAR(residual.x(), 0.0, 1e-12);
  EXPECT_NEAR(residual.y(), -std::sin(d) * w, 1e-12);
}

// A random mount, gyro bias and reading, and the rows' sigma in [0.01, 0.05] rad/s.
struct RandomCase {
  explicit RandomCase(std::mt19937* rng) {
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    q_I_V = Eigen::Quaterniond::UnitRandom();
    b_g = 0.02 * Eigen::Vector3d(u(*rng), u(*rng), u(*rng));
    m.gyro_rad_s = Eigen::Vector3d(u(*rng), u(*rng), u(*rng));
    m.sigma_rad_s = 0.03 + 0.02 * u(*rng);
  }
  std::vector<double*> Blocks() { return {b_g.data(), q_I_V.coeffs().data()}; }
  Eigen::Quaterniond q_I_V;
  Eigen::Vector3d b_g;
  PlanarRotationMeasurement m;
};

// The q_I_V Jacobian in its right tangent space (ambient Jacobian times PlusJacobian).
Eigen::Matrix<double, 2, 3> TangentJacobianOfMount(const ceres::CostFunction& cost,
                                                   const std::vector<double*>& blocks) {
  const geometry::RightQuaternionManifold quaternion;
  Eigen::Matrix<double, 4, 3, Eigen::RowMajor> plus;
  quaternion.PlusJacobian(blocks[1], plus.data());
  return test::Evaluate(cost, blocks).jacobians[1] * plus;
}

// The b_g Jacobian and the mount's roll and pitch columns are the residual's own (the
// autodiff twin's, and Ceres' GradientChecker on the b_g block); the yaw column is zero (Eq.
// F27b).
TEST(PlanarRotationFactor, JacobiansMatchAutodiffWithTheMountYawLeftOut) {
  const geometry::RightQuaternionManifold quaternion;
  std::mt19937 rng(8);
  for (int trial = 0; trial < 20; ++trial) {
    RandomCase state(&rng);
    const PlanarRotationFactor analytic(state.m);
    std::unique_ptr<ceres::CostFunction> autodiff(PlanarRotationResidual::CreateAutoDiff(state.m));
    const std::vector<double*> blocks = state.Blocks();
    const std::string context = "trial " + std::to_string(trial);
    const test::Evaluation a = test::Evaluate(analytic, blocks);
    const test::Evaluation b = test::Evaluate(*autodiff, blocks);
    EXPECT_LE((a.residual - b.residual).norm(), 1e-12 * b.residual.norm()) << context;
    EXPECT_LE((a.jacobians[0] - b.jacobians[0]).norm(), 1e-9 * b.jacobians[0].norm()) << context;
    const Eigen::Matrix<double, 2, 3> ja = TangentJacobianOfMount(analytic, blocks);
    const Eigen::Matrix<double, 2, 3> jb = TangentJacobianOfMount(*autodiff, blocks);
    EXPECT_LE((ja - ProjectOutMountYaw(jb)).norm(), 1e-9 * jb.norm()) << context;
    EXPECT_LE(ja.col(2).norm(), 1e-12 * ja.norm()) << context;  // through the ambient lift
    // Ceres' checker on b_g alone, the mount held.
    const std::vector<const ceres::Manifold*> manifolds = {nullptr, &quaternion};
    ceres::NumericDiffOptions numeric;
    ceres::GradientChecker checker(&analytic, &manifolds, numeric);
    ceres::GradientChecker::ProbeResults results;
    checker.Probe(blocks.data(), 1.0, &results);
    const test::RowMajorMatrix& j_bg = results.local_jacobians[0];
    const test::RowMajorMatrix& n_bg = results.local_numeric_jacobians[0];
    EXPECT_LE((j_bg - n_bg).norm(), 1e-6 * n_bg.norm()) << context;
  }
}

// Eq. F27b's premise: a turn of the mount about V's z turns the residual and keeps its norm, so
// the cost's derivative along it is zero, while the residual's own derivative there (the
// residual turned by 90 degrees) is not.
TEST(PlanarRotationFactor, TheRowsAreBlindToTheMountYaw) {
  std::mt19937 rng(5);
  for (int trial = 0; trial < 20; ++trial) {
    RandomCase state(&rng);
    std::unique_ptr<ceres::CostFunction> autodiff(PlanarRotationResidual::CreateAutoDiff(state.m));
    const std::vector<double*> blocks = state.Blocks();
    const Eigen::VectorXd r = test::Evaluate(*autodiff, blocks).residual;
    const Eigen::Vector2d yaw_column = TangentJacobianOfMount(*autodiff, blocks).col(2);
    EXPECT_NEAR(yaw_column.norm(), r.norm(), 1e-12 * r.norm()) << trial;
    EXPECT_NEAR(yaw_column.dot(r), 0.0, 1e-12 * r.squaredNorm()) << trial;
    for (double yaw : {0.3, -1.2, 2.5}) {
      Eigen::Quaterniond turned = state.q_I_V * Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ());
      const std::vector<double*> turned_blocks = {state.b_g.data(), turned.coeffs().data()};
      const Eigen::VectorXd r_turned = test::Evaluate(*autodiff, turned_blocks).residual;
      EXPECT_NEAR(r_turned.norm(), r.norm(), 1e-12 * r.norm()) << trial << ", yaw " << yaw;
      EXPECT_GT((r_turned - r).norm(), 0.1 * r.norm()) << trial << ", yaw " << yaw;
    }
  }
}

TEST(PlanarRotationFactor, RejectsBadInput) {
  PlanarRotationMeasurement m;
  m.sigma_rad_s = 0.0;
  EXPECT_THROW(PlanarRotationFactor{m}, Error);
  m.sigma_rad_s = std::nan("");
  EXPECT_THROW(PlanarRotationFactor{m}, Error);
  m.sigma_rad_s = 1.0;
  m.gyro_rad_s.z() = std::nan("");
  EXPECT_THROW(PlanarRotationFactor{m}, Error);
}

}  // namespace
}  // namespace factors
}  // namespace autocal
