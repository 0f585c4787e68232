#include "autocal/factors/planar_rotation_factor.h"

#include <ceres/ceres.h>
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
    m.sigma_rad_s = Eigen::Vector2d(0.02, 0.05);
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
  m.sigma_rad_s = Eigen::Vector2d::Ones();
  Eigen::Vector2d residual;
  std::vector<double*> blocks = {b_g.data(), q_I_V.coeffs().data()};
  ASSERT_TRUE(PlanarRotationFactor(m).Evaluate(blocks.data(), residual.data(), nullptr));
  EXPECT_NEAR(residual.x(), 0.0, 1e-12);
  EXPECT_NEAR(residual.y(), -std::sin(d) * w, 1e-12);
}

TEST(PlanarRotationFactor, JacobiansPassGradientCheckerAndMatchAutodiff) {
  const geometry::RightQuaternionManifold quaternion;
  const std::vector<const ceres::Manifold*> manifolds = {nullptr, &quaternion};
  std::mt19937 rng(8);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    Eigen::Quaterniond q_I_V = Eigen::Quaterniond::UnitRandom();
    Eigen::Vector3d b_g = 0.02 * Eigen::Vector3d(u(rng), u(rng), u(rng));
    PlanarRotationMeasurement m;
    m.gyro_rad_s = Eigen::Vector3d(u(rng), u(rng), u(rng));
    m.sigma_rad_s = Eigen::Vector2d(0.03 + 0.02 * u(rng), 0.03 + 0.02 * u(rng));
    const PlanarRotationFactor analytic(m);
    std::unique_ptr<ceres::CostFunction> autodiff(PlanarRotationResidual::CreateAutoDiff(m));
    const std::vector<double*> blocks = {b_g.data(), q_I_V.coeffs().data()};
    const std::string context = "trial " + std::to_string(trial);
    test::ExpectGradientCheckPasses(analytic, manifolds, blocks, 1e-6, context);
    test::ExpectSameJacobians(analytic, *autodiff, manifolds, blocks, 1e-9, context);
  }
}

TEST(PlanarRotationFactor, RejectsBadInput) {
  PlanarRotationMeasurement m;
  m.sigma_rad_s = Eigen::Vector2d(0.1, 0.0);
  EXPECT_THROW(PlanarRotationFactor{m}, Error);
  m.sigma_rad_s = Eigen::Vector2d(0.1, std::nan(""));
  EXPECT_THROW(PlanarRotationFactor{m}, Error);
  m.sigma_rad_s = Eigen::Vector2d::Ones();
  m.gyro_rad_s.z() = std::nan("");
  EXPECT_THROW(PlanarRotationFactor{m}, Error);
}

}  // namespace
}  // namespace factors
}  // namespace autocal
