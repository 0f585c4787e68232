#include <ceres/ceres.h>
#include <gtest/gtest.h>

#include <memory>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "autocal/factors/gnss_factor.h"
#include "autocal/factors/loss.h"
#include "autocal/factors/point_to_sweep_plane_group_factor.h"
#include "pipeline/residual_groups.h"

namespace autocal {
namespace pipeline {
namespace {

const estimation::ResidualSource& Named(const std::vector<estimation::ResidualSource>& sources,
                                        const std::string& name) {
  for (const estimation::ResidualSource& source : sources) {
    if (source.name == name) return source;
  }
  throw std::runtime_error("no source " + name);
}

// r = x: a prior of no sensor.
struct Identity {
  template <typename T>
  bool operator()(const T* x, T* r) const {
    for (int i = 0; i < 3; ++i) r[i] = x[i];
    return true;
  }
};

double Ratio(const factors::RowPull& pull) { return pull.pull_squared / pull.weight; }

// Eq. C8b: a stated sensor's share ratio is its loss's expectation for rows N(0, I) of each
// block's dimension, pooled over its blocks; the points' is their own distances' (Eq. P10
// measures their sigma from them); a block without a loss has 1.
TEST(ResidualSources, ShareRatiosFollowEachSourcesLossAndRows) {
  ceres::Problem problem;
  Eigen::Quaterniond q_W_I = Eigen::Quaterniond::Identity();
  Eigen::Vector3d p_W_I = Eigen::Vector3d::Zero(), p_I_A(0.1, 0.2, 0.9);
  const factors::LossOptions cauchy_3{factors::RobustLoss::kCauchy, 3.0};
  ceres::LossFunction* gnss_loss = factors::MakeLossFunction(cauchy_3);
  factors::GnssMeasurement fix;
  fix.p_W_A = Eigen::Vector3d(0.3, -0.2, 1.0);
  fix.sigma_enu_m = Eigen::Vector3d(0.02, 0.02, 0.05);
  problem.AddResidualBlock(factors::GnssFactor::Create(fix), gnss_loss, q_W_I.coeffs().data(),
                           p_W_I.data(), p_I_A.data());
  problem.AddResidualBlock(factors::GnssFactor::Create(fix, factors::GnssAxes::kHorizontal),
                           gnss_loss, q_W_I.coeffs().data(), p_W_I.data(), p_I_A.data());

  // Points of a sweep pair with identity states and motions: each whitened distance is the
  // plane offset it was given, r_i sigma.
  std::mt19937 rng(3);
  std::normal_distribution<double> gauss;
  std::vector<factors::PointToSweepPlaneMeasurement> points(400);
  const std::unique_ptr<ceres::LossFunction> huber_1(
      factors::MakeLossFunction({factors::RobustLoss::kHuber, 1.0}));
  factors::SandwichRatio distances(huber_1.get());
  for (factors::PointToSweepPlaneMeasurement& m : points) {
    m.p_L = Eigen::Vector3d(5.0 * gauss(rng), 5.0 * gauss(rng), gauss(rng));
    m.plane_L.normal = Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng)).normalized();
    const double r = 1.5 * gauss(rng);  // a heavier spread than the stated sigma
    m.plane_L.d = -m.plane_L.normal.dot(m.p_L) + r * m.sigma_m;
    distances.Add(r);
  }
  std::vector<Eigen::Quaterniond> q(3, Eigen::Quaterniond::Identity());
  std::vector<Eigen::Vector3d> v(6, Eigen::Vector3d::Zero());
  double offset_s = 0.0;
  problem.AddResidualBlock(
      new factors::PointToSweepPlaneGroupFactor(points, Eigen::Vector3d(0.0, 0.0, -9.80665),
                                                {factors::RobustLoss::kHuber, 1.0}),
      nullptr,
      {q[0].coeffs().data(), v[0].data(), v[1].data(), q[1].coeffs().data(), v[2].data(),
       v[3].data(), q[2].coeffs().data(), v[4].data(), &offset_s});
  problem.AddResidualBlock(new ceres::AutoDiffCostFunction<Identity, 3, 3>(new Identity), nullptr,
                           v[5].data());

  const std::vector<estimation::ResidualSource> sources = ResidualSources(&problem);
  ASSERT_EQ(sources.size(), 3u);
  const factors::RowPull three = factors::ExpectedRowPull(gnss_loss, 3);
  const factors::RowPull two = factors::ExpectedRowPull(gnss_loss, 2);
  EXPECT_NEAR(Named(sources, "gnss").share_ratio,
              (three.pull_squared + two.pull_squared) / (three.weight + two.weight), 1e-12);
  EXPECT_NEAR(Ratio(three), 0.6045, 1e-3);
  EXPECT_NEAR(Named(sources, "lidar").share_ratio, Ratio(distances.pull()), 1e-12);
  // Measured, not expected: distances 1.5 times their stated sigma give 0.94, not 0.57.
  EXPECT_GT(Named(sources, "lidar").share_ratio - Ratio(factors::ExpectedRowPull(huber_1.get(), 1)),
            0.3);
  EXPECT_EQ(Named(sources, "priors").share_ratio, 1.0);
}

}  // namespace
}  // namespace pipeline
}  // namespace autocal
