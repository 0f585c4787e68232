// Marginalizing the oldest keyframe of a sliding window: its IMU factor to the next keyframe
// and the point-to-plane residuals of its sweep (which also touch the calibration blocks).
#include <benchmark/benchmark.h>
#include <ceres/ceres.h>

#include <memory>
#include <random>
#include <vector>

#include "autocal/estimation/marginalization.h"
#include "autocal/factors/imu_factor.h"
#include "autocal/factors/point_to_plane_factor.h"
#include "autocal/geometry/manifolds.h"
#include "autocal/geometry/so3.h"
#include "autocal/sensors/imu_preintegration.h"

namespace autocal {
namespace {

struct State {
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  Eigen::Vector3d p = Eigen::Vector3d::Zero(), v = Eigen::Vector3d::Zero();
  Eigen::Vector3d bg = Eigen::Vector3d::Zero(), ba = Eigen::Vector3d::Zero();
};

void BM_MarginalizeOldestKeyframe(benchmark::State& bench) {
  const int points = static_cast<int>(bench.range(0));
  const Eigen::Vector3d g(0.0, 0.0, -9.80665);
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  // Two keyframes 0.1 s apart driving forward at 10 m/s, turning slowly.
  sensors::ImuPreintegration pim{sensors::ImuNoise{}, sensors::PreintegrationOptions{}};
  for (int i = 0; i < 20; ++i) {
    pim.IntegrateStep(Eigen::Vector3d(0.0, 0.0, 0.1), Eigen::Vector3d(0.2, 0.0, 9.80665), 0.005);
  }
  for (auto _ : bench) {
    bench.PauseTiming();
    State a, b;
    a.v = Eigen::Vector3d(10.0, 0.0, 0.0);
    b.p = Eigen::Vector3d(1.0, 0.0, 0.0);
    b.v = a.v;
    Eigen::Quaterniond q_I_L = geometry::Exp(Eigen::Vector3d(0.02, -0.03, 0.05));
    Eigen::Vector3d p_I_L(0.3, 0.0, 0.5);
    double offset = 0.02;
    ceres::Problem::Options options;
    options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    geometry::RightQuaternionManifold manifold;
    ceres::Problem problem(options);
    for (State* s : {&a, &b}) problem.AddParameterBlock(s->q.coeffs().data(), 4, &manifold);
    problem.AddParameterBlock(q_I_L.coeffs().data(), 4, &manifold);
    problem.AddResidualBlock(factors::ImuFactor::Create(pim), nullptr, a.q.coeffs().data(),
                             a.p.data(), a.v.data(), a.bg.data(), a.ba.data(), b.q.coeffs().data(),
                             b.p.data(), b.v.data(), b.bg.data(), b.ba.data());
    ceres::LossFunction* loss = new ceres::CauchyLoss(2.0);
    for (int i = 0; i < points; ++i) {
      factors::PointToPlaneMeasurement m;
      m.p_L = 20.0 * Eigen::Vector3d(u(rng), u(rng), 0.1 * u(rng));
      m.motion.dt_s = 0.05 * (u(rng) + 1.0);
      m.plane.normal = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
      m.plane.d = 5.0 * u(rng);
      problem.AddResidualBlock(new factors::PointToPlaneFactor(m, g), loss, a.q.coeffs().data(),
                               a.p.data(), a.v.data(), q_I_L.coeffs().data(), p_I_L.data(),
                               &offset);
    }
    bench.ResumeTiming();
    auto prior = estimation::Marginalize(
        &problem, {a.q.coeffs().data(), a.p.data(), a.v.data(), a.bg.data(), a.ba.data()});
    benchmark::DoNotOptimize(prior);
  }
}
BENCHMARK(BM_MarginalizeOldestKeyframe)->Arg(2000)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace autocal

BENCHMARK_MAIN();
