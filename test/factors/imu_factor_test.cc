#include "autocal/factors/imu_factor.h"

#include <ceres/ceres.h>
#include <gtest/gtest.h>

#include <iostream>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "autocal/geometry/manifolds.h"
#include "factors/factor_test_utils.h"
#include "sensors/imu_test_trajectory.h"

namespace autocal {
namespace factors {
namespace {

const Eigen::Vector3d kGravity(0.0, 0.0, -9.80665);

// One keyframe's parameter blocks in the order the factor takes them.
struct StateBlocks {
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  Eigen::Vector3d v = Eigen::Vector3d::Zero();
  Eigen::Vector3d b_g = Eigen::Vector3d::Zero();
  Eigen::Vector3d b_a = Eigen::Vector3d::Zero();
};

std::vector<double*> Blocks(StateBlocks* i, StateBlocks* j) {
  return {i->q.coeffs().data(), i->p.data(), i->v.data(), i->b_g.data(), i->b_a.data(),
          j->q.coeffs().data(), j->p.data(), j->v.data(), j->b_g.data(), j->b_a.data()};
}

std::vector<const ceres::Manifold*> Manifolds(const ceres::Manifold* quaternion) {
  return {quaternion, nullptr, nullptr, nullptr, nullptr,
          quaternion, nullptr, nullptr, nullptr, nullptr};
}

StateBlocks TrueState(const test::ImuTrajectory& trajectory, double t, const Eigen::Vector3d& b_g,
                      const Eigen::Vector3d& b_a) {
  StateBlocks s;
  s.q = trajectory.q_W_I(t);
  s.p = trajectory.p_W_I(t);
  s.v = trajectory.v_W_I(t);
  s.b_g = b_g;
  s.b_a = b_a;
  return s;
}

// A keyframe interval of a random smooth drive with biased IMU samples, integrated with
// linearization biases b_g_lin, b_a_lin.
struct Scenario {
  std::unique_ptr<test::SmoothTrajectory> trajectory;
  Eigen::Vector3d b_g, b_a;
  double t_i, t_j;
  std::unique_ptr<sensors::ImuPreintegration> pim;
};

Scenario MakeScenario(uint32_t seed, const Eigen::Vector3d& b_g_lin_offset,
                      const Eigen::Vector3d& b_a_lin_offset) {
  Scenario s;
  s.trajectory = std::make_unique<test::SmoothTrajectory>(test::SmoothTrajectory::Random(seed));
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  s.b_g = Eigen::Vector3d(u(rng), u(rng), u(rng)) * 0.02;
  s.b_a = Eigen::Vector3d(u(rng), u(rng), u(rng)) * 0.2;
  const sensors::ImuSamples samples =
      test::SampleImu(*s.trajectory, 0, 1'250'000, 400, kGravity, s.b_g, s.b_a);
  const int64_t t_i_ns = 10'100'000, t_j_ns = 310'100'000;
  s.t_i = NsToSeconds(t_i_ns);
  s.t_j = NsToSeconds(t_j_ns);
  s.pim = std::make_unique<sensors::ImuPreintegration>(
      sensors::ImuNoise(), sensors::PreintegrationOptions(), s.b_g + b_g_lin_offset,
      s.b_a + b_a_lin_offset);
  s.pim->Integrate(samples, t_i_ns, t_j_ns);
  return s;
}

// At the true states and biases the residual is the discretization error only (800 Hz
// samples), far below one standard deviation of the preintegration noise.
TEST(ImuFactor, ResidualVanishesAtGroundTruth) {
  for (uint32_t seed : {1u, 2u, 3u}) {
    Scenario s = MakeScenario(seed, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
    StateBlocks i = TrueState(*s.trajectory, s.t_i, s.b_g, s.b_a);
    StateBlocks j = TrueState(*s.trajectory, s.t_j, s.b_g, s.b_a);
    const ImuFactor factor(*s.pim);
    Eigen::Matrix<double, 15, 1> residual;
    const std::vector<double*> blocks = Blocks(&i, &j);
    ASSERT_TRUE(factor.Evaluate(blocks.data(), residual.data(), nullptr));
    EXPECT_LT(residual.lpNorm<Eigen::Infinity>(), 0.05)
        << "seed " << seed << ": whitened residual " << residual.transpose();
    // A 1 cm error in p_j is many standard deviations: the factor is not blind.
    j.p.x() += 0.01;
    ASSERT_TRUE(factor.Evaluate(blocks.data(), residual.data(), nullptr));
    EXPECT_GT(residual.norm(), 10.0) << "seed " << seed;
  }
}

// Monte-Carlo at the true states: white noise on every sample and the biases' random walk
// over the interval (b_i the start's bias, b_j the end's). The whitened residual must be
// standard normal, its cross terms included: its delta rows are truth minus measurement, its
// bias rows the drift, so a bias that drifts up pulls the velocity and position rows down, and
// the whitening must know that sign (Eq. F11).
TEST(ImuFactor, WhitenedResidualIsStandardNormalAtTheTruth) {
  const test::SmoothTrajectory trajectory = test::SmoothTrajectory::Random(13, 2.0, 1.0);
  constexpr int64_t kPeriodNs = 5'000'000;
  constexpr int kSamples = 201;  // 1 s at 200 Hz: a keyframe interval without the LiDAR
  constexpr int kDraws = 3000;
  const double dt = NsToSeconds(kPeriodNs);
  sensors::ImuNoise noise;
  noise.gyroscope_random_walk = 2e-3;  // the drift matters within the interval
  noise.accelerometer_random_walk = 2e-2;
  const sensors::ImuSamples clean = test::SampleImu(trajectory, 0, kPeriodNs, kSamples, kGravity);
  const int64_t t_end_ns = (kSamples - 1) * kPeriodNs;
  sensors::PreintegrationOptions options;
  options.gravity_m_s2 = -kGravity.z();
  std::mt19937 rng(2026);
  std::normal_distribution<double> n01(0.0, 1.0);
  const auto gauss = [&]() { return Eigen::Vector3d(n01(rng), n01(rng), n01(rng)); };
  Eigen::Matrix<double, 15, 15> sample_cov = Eigen::Matrix<double, 15, 15>::Zero();
  for (int draw = 0; draw < kDraws; ++draw) {
    Eigen::Vector3d b_g, b_a;
    const sensors::ImuSamples noisy = test::NoisyDraw(clean, dt, noise, gauss, &b_g, &b_a);
    sensors::ImuPreintegration pim(noise, options);
    pim.Integrate(noisy, 0, t_end_ns);
    StateBlocks i = TrueState(trajectory, 0.0, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
    StateBlocks j = TrueState(trajectory, NsToSeconds(t_end_ns), b_g, b_a);
    const ImuFactor factor(pim);
    Eigen::Matrix<double, 15, 1> r;
    const std::vector<double*> blocks = Blocks(&i, &j);
    ASSERT_TRUE(factor.Evaluate(blocks.data(), r.data(), nullptr));
    sample_cov += r * r.transpose() / kDraws;
  }
  // Each entry of the sample covariance of a standard normal vector has a standard error of
  // at most sqrt(2 / kDraws) = 0.026 on the diagonal and 0.018 off it.
  for (int a = 0; a < 15; ++a) {
    for (int b = 0; b < 15; ++b) {
      EXPECT_NEAR(sample_cov(a, b), a == b ? 1.0 : 0.0, a == b ? 0.11 : 0.08)
          << "rows " << a << ", " << b;
    }
  }
  EXPECT_NEAR(sample_cov.trace(), 15.0, 0.6);
  const Eigen::Matrix<double, 15, 15> off =
      sample_cov - Eigen::Matrix<double, 15, 15>(sample_cov.diagonal().asDiagonal());
  std::cout << "whitened residual: trace " << sample_cov.trace() << ", diagonal "
            << sample_cov.diagonal().minCoeff() << "-" << sample_cov.diagonal().maxCoeff()
            << ", largest cross term " << off.cwiseAbs().maxCoeff() << "\n";
}

// Random states far from the truth: large rotations on both keyframes, non-zero biases away
// from the linearization point.
void RandomizeStates(std::mt19937* rng, StateBlocks* i, StateBlocks* j) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  auto vec = [&](double s) -> Eigen::Vector3d {
    return Eigen::Vector3d(u(*rng), u(*rng), u(*rng)) * s;
  };
  i->q = Eigen::Quaterniond::UnitRandom();
  j->q = i->q * geometry::Exp(vec(1.2));
  i->p = vec(20.0);
  j->p = i->p + vec(5.0);
  i->v = vec(10.0);
  j->v = vec(10.0);
  i->b_g += vec(0.05);
  i->b_a += vec(0.5);
  j->b_g = vec(0.05);
  j->b_a = vec(0.5);
}

TEST(ImuFactor, JacobiansPassGradientCheckerAndMatchAutodiff) {
  const geometry::RightQuaternionManifold quaternion;
  std::mt19937 rng(77);
  for (int trial = 0; trial < 12; ++trial) {
    Scenario s = MakeScenario(100 + trial, Eigen::Vector3d(0.004, -0.003, 0.002),
                              Eigen::Vector3d(-0.03, 0.02, 0.05));
    StateBlocks i = TrueState(*s.trajectory, s.t_i, s.b_g, s.b_a);
    StateBlocks j = TrueState(*s.trajectory, s.t_j, s.b_g, s.b_a);
    if (trial > 1) RandomizeStates(&rng, &i, &j);
    const std::vector<double*> blocks = Blocks(&i, &j);
    const std::string context = "trial " + std::to_string(trial);
    const ImuFactor analytic(*s.pim);
    std::unique_ptr<ceres::CostFunction> autodiff(ImuResidual::CreateAutoDiff(*s.pim));
    test::ExpectGradientCheckPasses(analytic, Manifolds(&quaternion), blocks, 1e-4, context);
    test::ExpectCentralDifferencesMatch(analytic, Manifolds(&quaternion), blocks, 1e-5, 1e-7,
                                        context);
    test::ExpectSameJacobians(analytic, *autodiff, Manifolds(&quaternion), blocks, 1e-9, context);
  }
}

// In a small problem, keyframe j starting 0.3 rad and 1 m off returns to the truth when
// keyframe i is held fixed.
TEST(ImuFactor, RecoversTheNextKeyframeInASolve) {
  Scenario s = MakeScenario(42, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
  StateBlocks i = TrueState(*s.trajectory, s.t_i, s.b_g, s.b_a);
  const StateBlocks truth_j = TrueState(*s.trajectory, s.t_j, s.b_g, s.b_a);
  StateBlocks j = truth_j;
  j.q = j.q * geometry::Exp(Eigen::Vector3d(0.2, -0.2, 0.1));
  j.p += Eigen::Vector3d(1.0, -0.5, 0.3);
  j.v += Eigen::Vector3d(-0.4, 0.2, 0.1);
  ceres::Problem problem;
  const std::vector<double*> blocks = Blocks(&i, &j);
  problem.AddResidualBlock(ImuFactor::Create(*s.pim), nullptr, blocks);
  problem.SetManifold(i.q.coeffs().data(), new geometry::RightQuaternionManifold);
  problem.SetManifold(j.q.coeffs().data(), new geometry::RightQuaternionManifold);
  for (int k = 0; k < 5; ++k) problem.SetParameterBlockConstant(blocks[k]);
  ceres::Solver::Options options;
  options.max_num_iterations = 20;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  EXPECT_LT(geometry::AngularDistance(j.q, truth_j.q), 1e-5) << summary.BriefReport();
  EXPECT_LT((j.p - truth_j.p).norm(), 1e-4) << j.p.transpose() << " vs " << truth_j.p.transpose();
  EXPECT_LT((j.v - truth_j.v).norm(), 1e-4) << j.v.transpose() << " vs " << truth_j.v.transpose();
}

}  // namespace
}  // namespace factors
}  // namespace autocal
