#include "autocal/factors/gnss_factor.h"

#include <ceres/ceres.h>
#include <gtest/gtest.h>

#include <memory>
#include <random>
#include <string>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/geometry/manifolds.h"
#include "factors/factor_test_utils.h"
#include "sensors/imu_test_trajectory.h"

namespace autocal {
namespace factors {
namespace {

std::vector<const ceres::Manifold*> Manifolds(const ceres::Manifold* quaternion) {
  return {quaternion, nullptr, nullptr};
}

TEST(GnssFactor, ResidualVanishesAtGroundTruth) {
  const test::SmoothTrajectory trajectory = test::SmoothTrajectory::Random(4, 20.0, 2.0);
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int k = 0; k < 20; ++k) {
    const double t = 0.37 * k;
    Eigen::Quaterniond q = trajectory.q_W_I(t);
    Eigen::Vector3d p = trajectory.p_W_I(t);
    Eigen::Vector3d p_I_A(u(rng), u(rng), 1.5 + u(rng));
    GnssMeasurement m;
    m.p_W_A = p + q * p_I_A;
    m.sigma_enu_m = Eigen::Vector3d(0.02, 0.03, 0.05);
    const GnssFactor factor(m);
    Eigen::Vector3d residual;
    const std::vector<double*> blocks = {q.coeffs().data(), p.data(), p_I_A.data()};
    ASSERT_TRUE(factor.Evaluate(blocks.data(), residual.data(), nullptr));
    EXPECT_LT(residual.norm(), 1e-9) << "t = " << t << ": " << residual.transpose();
    // Whitening: 1 sigma north is a unit residual.
    p.y() += 0.03;
    ASSERT_TRUE(factor.Evaluate(blocks.data(), residual.data(), nullptr));
    EXPECT_NEAR(residual.y(), 1.0, 1e-9) << "t = " << t;
  }
}

TEST(GnssFactor, JacobiansPassGradientCheckerAndMatchAutodiff) {
  const geometry::RightQuaternionManifold quaternion;
  std::mt19937 rng(6);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    Eigen::Quaterniond q = Eigen::Quaterniond::UnitRandom();
    Eigen::Vector3d p = Eigen::Vector3d(u(rng), u(rng), u(rng)) * 100.0;
    Eigen::Vector3d p_I_A = Eigen::Vector3d(u(rng), u(rng), u(rng)) * 2.0;
    GnssMeasurement m;
    m.p_W_A = Eigen::Vector3d(u(rng), u(rng), u(rng)) * 100.0;
    m.sigma_enu_m = Eigen::Vector3d(1.0 + 0.5 * u(rng), 1.0 + 0.5 * u(rng), 2.0 + u(rng)) * 0.1;
    const std::vector<double*> blocks = {q.coeffs().data(), p.data(), p_I_A.data()};
    for (const GnssAxes axes : {GnssAxes::kAll, GnssAxes::kHorizontal, GnssAxes::kVertical}) {
      const GnssFactor analytic(m, axes);
      std::unique_ptr<ceres::CostFunction> autodiff(GnssResidual::CreateAutoDiff(m, axes));
      const std::string context =
          "trial " + std::to_string(trial) + ", rows " + std::to_string(NumRows(axes));
      test::ExpectGradientCheckPasses(analytic, Manifolds(&quaternion), blocks, 1e-6, context);
      test::ExpectSameJacobians(analytic, *autodiff, Manifolds(&quaternion), blocks, 1e-9, context);
    }
  }
}

// The horizontal and vertical factors carry the all-rows factor's rows: east and north, up.
TEST(GnssFactor, AxesSelectTheRowsOfTheWholeFactor) {
  Eigen::Quaterniond q = Eigen::Quaterniond::UnitRandom();
  Eigen::Vector3d p(3.0, -4.0, 5.0), p_I_A(0.2, -0.1, 1.4);
  GnssMeasurement m;
  m.p_W_A = Eigen::Vector3d(2.5, -3.0, 7.0);
  m.sigma_enu_m = Eigen::Vector3d(0.5, 0.7, 1.5);
  const std::vector<double*> blocks = {q.coeffs().data(), p.data(), p_I_A.data()};
  Eigen::Vector3d all, horizontal;
  double vertical = 0.0;
  ASSERT_TRUE(GnssFactor(m).Evaluate(blocks.data(), all.data(), nullptr));
  const GnssFactor h(m, GnssAxes::kHorizontal), v(m, GnssAxes::kVertical);
  EXPECT_EQ(h.num_residuals(), 2);
  EXPECT_EQ(v.num_residuals(), 1);
  ASSERT_TRUE(h.Evaluate(blocks.data(), horizontal.data(), nullptr));
  ASSERT_TRUE(v.Evaluate(blocks.data(), &vertical, nullptr));
  EXPECT_EQ(horizontal.head<2>(), all.head<2>());
  EXPECT_EQ(vertical, all.z());
}

// A fix whose altitude is far off: with its rows split, the robust loss down-weights only the
// vertical block and keeps the horizontal position at full weight.
TEST(GnssFactor, AnAltitudeOutlierLeavesTheHorizontalRowsTheirWeight) {
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  Eigen::Vector3d p = Eigen::Vector3d::Zero(), p_I_A = Eigen::Vector3d::Zero();
  GnssMeasurement m;
  m.p_W_A = Eigen::Vector3d(0.5, -0.5, 20.0);  // 0.5 sigma east and north, 10 sigma up
  m.sigma_enu_m = Eigen::Vector3d(1.0, 1.0, 2.0);
  ceres::CauchyLoss cauchy(3.0);
  const auto weight = [&](GnssAxes axes) {
    const GnssFactor factor(m, axes);
    const std::vector<double*> blocks = {q.coeffs().data(), p.data(), p_I_A.data()};
    double r[3] = {0.0, 0.0, 0.0};
    EXPECT_TRUE(factor.Evaluate(blocks.data(), r, nullptr));
    const double squared_norm = r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
    double rho[3];
    cauchy.Evaluate(squared_norm, rho);
    return rho[1];  // the IRLS weight of the block's rows
  };
  EXPECT_GT(weight(GnssAxes::kHorizontal), 0.9);  // 1 / (1 + 0.5 / 9) for its 0.7 sigma
  EXPECT_LT(weight(GnssAxes::kVertical), 0.1);
  EXPECT_LT(weight(GnssAxes::kAll), 0.1);  // one block: the horizontal rows lose it too
}

// The lever arm is observable once the vehicle rotates: recovered from noisy fixes along a
// trajectory with known poses.
TEST(GnssFactor, RecoversTheLeverArm) {
  const test::SmoothTrajectory trajectory = test::SmoothTrajectory::Random(12, 20.0, 1.5);
  const Eigen::Vector3d true_p_I_A(0.8, -0.3, 1.4);
  std::mt19937 rng(12);
  std::normal_distribution<double> noise(0.0, 0.02);
  std::vector<Eigen::Quaterniond> q(200);
  std::vector<Eigen::Vector3d> p(200);
  Eigen::Vector3d p_I_A = Eigen::Vector3d::Zero();
  ceres::Problem problem;
  for (size_t k = 0; k < q.size(); ++k) {
    const double t = 0.1 * static_cast<double>(k);
    q[k] = trajectory.q_W_I(t);
    p[k] = trajectory.p_W_I(t);
    GnssMeasurement m;
    m.p_W_A = p[k] + q[k] * true_p_I_A + Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    m.sigma_enu_m = Eigen::Vector3d::Constant(0.02);
    problem.AddResidualBlock(GnssFactor::Create(m), nullptr, q[k].coeffs().data(), p[k].data(),
                             p_I_A.data());
    problem.SetParameterBlockConstant(q[k].coeffs().data());
    problem.SetParameterBlockConstant(p[k].data());
  }
  ceres::Solver::Options options;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  EXPECT_LT((p_I_A - true_p_I_A).norm(), 0.01)
      << p_I_A.transpose() << " vs " << true_p_I_A.transpose() << "\n"
      << summary.BriefReport();
}

TEST(GnssFactor, RejectsBadSigmas) {
  GnssMeasurement m;
  m.sigma_enu_m = Eigen::Vector3d(0.1, 0.0, 0.1);
  EXPECT_THROW(GnssFactor{m}, Error);
  m.sigma_enu_m = Eigen::Vector3d(0.1, std::nan(""), 0.1);
  EXPECT_THROW(GnssFactor{m}, Error);
  m.sigma_enu_m = Eigen::Vector3d::Ones();
  m.p_W_A.x() = std::nan("");
  EXPECT_THROW(GnssFactor{m}, Error);
  const sensors::EnuConverter converter(49.0, 8.4, 110.0);
  sensors::GnssFix fix;
  fix.lat_deg = 49.001;
  fix.lon_deg = 8.4;
  fix.std_enu_m = Eigen::Vector3d(0.02, -0.02, 0.05);
  EXPECT_THROW(GnssMeasurement::FromFix(fix, converter), Error);
}

}  // namespace
}  // namespace factors
}  // namespace autocal
