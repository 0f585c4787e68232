// Cost of one LiDAR point-to-plane residual with all Jacobians, analytic vs autodiff twin:
// against a plane held in W, and against a plane of another sweep, alone and in a group.
#include <benchmark/benchmark.h>

#include <memory>
#include <random>
#include <vector>

#include "autocal/factors/point_to_plane_factor.h"
#include "autocal/factors/point_to_sweep_plane_factor.h"
#include "autocal/factors/point_to_sweep_plane_group_factor.h"
#include "autocal/geometry/so3.h"

namespace autocal {
namespace {

constexpr int kPoints = 2000;  // a typical sweep after downsampling

std::vector<factors::PointToPlaneMeasurement> RandomMeasurements() {
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<factors::PointToPlaneMeasurement> out(kPoints);
  for (auto& m : out) {
    m.p_L = 20.0 * Eigen::Vector3d(u(rng), u(rng), u(rng));
    m.motion.dt_s = 0.05 * (u(rng) + 1.0);
    m.motion.delta_q = geometry::Exp(Eigen::Vector3d(0.05 * u(rng), 0.05 * u(rng), 0.05 * u(rng)));
    m.motion.delta_v = Eigen::Vector3d(u(rng), u(rng), u(rng));
    m.motion.delta_p = 0.1 * Eigen::Vector3d(u(rng), u(rng), u(rng));
    m.motion.omega_rad_s = 0.3 * Eigen::Vector3d(u(rng), u(rng), u(rng));
    m.plane.normal = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
    m.plane.d = 5.0 * u(rng);
  }
  return out;
}

template <bool kAnalytic>
void BM_PointToPlaneEvaluate(benchmark::State& state) {
  const Eigen::Vector3d g(0.0, 0.0, -9.80665);
  std::vector<std::unique_ptr<ceres::CostFunction>> costs;
  for (const auto& m : RandomMeasurements()) {
    costs.emplace_back(kAnalytic ? new factors::PointToPlaneFactor(m, g)
                                 : factors::CreatePointToPlaneAutoDiff(m, g));
  }
  Eigen::Quaterniond q_W_I = geometry::Exp(Eigen::Vector3d(0.1, 0.2, 1.0));
  Eigen::Vector3d p_W_I(10.0, -4.0, 1.0), v_W_I(8.0, 1.0, 0.0);
  Eigen::Quaterniond q_I_L = geometry::Exp(Eigen::Vector3d(0.02, -0.03, 0.5));
  Eigen::Vector3d p_I_L(0.3, 0.0, 0.4);
  double offset_s = 0.01;
  const double* params[] = {q_W_I.coeffs().data(), p_W_I.data(), v_W_I.data(),
                            q_I_L.coeffs().data(), p_I_L.data(), &offset_s};
  double j0[4], j1[3], j2[3], j3[4], j4[3], j5[1];
  double* jacobians[] = {j0, j1, j2, j3, j4, j5};
  double residual = 0.0;
  for (auto _ : state) {
    for (const auto& cost : costs) {
      cost->Evaluate(params, &residual, jacobians);
      benchmark::DoNotOptimize(residual);
      benchmark::DoNotOptimize(j5[0]);
    }
  }
  // items_per_second is points per second; the time per point is its inverse.
  state.SetItemsProcessed(state.iterations() * kPoints);
}

BENCHMARK_TEMPLATE(BM_PointToPlaneEvaluate, true)->Name("PointToPlane/analytic");
BENCHMARK_TEMPLATE(BM_PointToPlaneEvaluate, false)->Name("PointToPlane/autodiff");

// The same points against planes of another sweep (two keyframes, Eq. P6-P8).
std::vector<factors::PointToSweepPlaneMeasurement> RandomSweepMeasurements() {
  std::vector<factors::PointToSweepPlaneMeasurement> out;
  for (const auto& m : RandomMeasurements()) {
    factors::PointToSweepPlaneMeasurement sweep_m;
    sweep_m.p_L = m.p_L;
    sweep_m.motion = m.motion;
    sweep_m.plane_motion.dt_s = 0.02;
    sweep_m.plane_motion.delta_q = geometry::Exp(Eigen::Vector3d(0.001, 0.002, 0.01));
    sweep_m.plane_motion.delta_v = Eigen::Vector3d(0.2, 0.0, 0.0);
    sweep_m.plane_motion.delta_p = Eigen::Vector3d(0.002, 0.0, 0.0);
    sweep_m.plane_motion.omega_rad_s = Eigen::Vector3d(0.0, 0.0, 0.3);
    sweep_m.plane_L = m.plane;
    out.push_back(sweep_m);
  }
  return out;
}

// Two keyframes, an extrinsic and an offset for the sweep-plane benchmarks.
struct SweepPairState {
  Eigen::Quaterniond q_k = geometry::Exp(Eigen::Vector3d(0.1, 0.2, 1.0));
  Eigen::Quaterniond q_j = geometry::Exp(Eigen::Vector3d(0.1, 0.2, 1.3));
  Eigen::Vector3d p_k{10.0, -4.0, 1.0}, v_k{8.0, 1.0, 0.0}, p_j{14.0, -3.0, 1.0},
      v_j{8.0, 2.0, 0.0};
  Eigen::Quaterniond q_I_L = geometry::Exp(Eigen::Vector3d(0.02, -0.03, 0.5));
  Eigen::Vector3d p_I_L{0.3, 0.0, 0.4};
  double offset_s = 0.01;
  std::vector<const double*> Blocks() const {
    return {q_k.coeffs().data(),   p_k.data(),   v_k.data(),
            q_j.coeffs().data(),   p_j.data(),   v_j.data(),
            q_I_L.coeffs().data(), p_I_L.data(), &offset_s};
  }
};

template <bool kAnalytic>
void BM_PointToSweepPlaneEvaluate(benchmark::State& state) {
  const Eigen::Vector3d g(0.0, 0.0, -9.80665);
  std::vector<std::unique_ptr<ceres::CostFunction>> costs;
  for (const auto& sweep_m : RandomSweepMeasurements()) {
    costs.emplace_back(kAnalytic ? new factors::PointToSweepPlaneFactor(sweep_m, g)
                                 : factors::CreatePointToSweepPlaneAutoDiff(sweep_m, g));
  }
  const SweepPairState x;
  const std::vector<const double*> blocks = x.Blocks();
  const double* const* params = blocks.data();
  double j0[4], j1[3], j2[3], j3[4], j4[3], j5[3], j6[4], j7[3], j8[1];
  double* jacobians[] = {j0, j1, j2, j3, j4, j5, j6, j7, j8};
  double residual = 0.0;
  for (auto _ : state) {
    for (const auto& cost : costs) {
      cost->Evaluate(params, &residual, jacobians);
      benchmark::DoNotOptimize(residual);
      benchmark::DoNotOptimize(j8[0]);
    }
  }
  state.SetItemsProcessed(state.iterations() * kPoints);
}

BENCHMARK_TEMPLATE(BM_PointToSweepPlaneEvaluate, true)->Name("PointToSweepPlane/analytic");
BENCHMARK_TEMPLATE(BM_PointToSweepPlaneEvaluate, false)->Name("PointToSweepPlane/autodiff");

// The same points as one group of a pair of sweeps (Eq. P9, no loss), as the sliding window
// and the batch solver evaluate them: the rotations and lifts are shared by the points.
void BM_PointToSweepPlaneGroupEvaluate(benchmark::State& state) {
  const factors::PointToSweepPlaneGroupFactor group(
      RandomSweepMeasurements(), Eigen::Vector3d(0.0, 0.0, -9.80665), factors::LossOptions());
  const SweepPairState x;
  const std::vector<const double*> params = x.Blocks();
  const std::vector<int> sizes = {4, 3, 3, 4, 3, 3, 4, 3, 1};
  std::vector<std::vector<double>> storage;
  std::vector<double*> jacobians;
  for (int size : sizes) {
    storage.emplace_back(static_cast<size_t>(size * kPoints));
    jacobians.push_back(storage.back().data());
  }
  std::vector<double> residuals(kPoints);
  for (auto _ : state) {
    group.Evaluate(params.data(), residuals.data(), jacobians.data());
    benchmark::DoNotOptimize(residuals.data());
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * kPoints);
}

BENCHMARK(BM_PointToSweepPlaneGroupEvaluate)->Name("PointToSweepPlaneGroup/analytic");

// The same group in its 22 tangent columns, column-major, as the sliding window's compressed
// point groups linearize it (PointToSweepPlaneGroupFactor::EvaluateTangent).
void BM_PointToSweepPlaneGroupTangent(benchmark::State& state) {
  const factors::PointToSweepPlaneGroupFactor group(
      RandomSweepMeasurements(), Eigen::Vector3d(0.0, 0.0, -9.80665), factors::LossOptions());
  const SweepPairState x;
  const std::vector<const double*> params = x.Blocks();
  std::vector<double> jacobian(
      static_cast<size_t>(factors::PointToSweepPlaneGroupFactor::kTangentColumns * kPoints));
  std::vector<double> residuals(kPoints);
  for (auto _ : state) {
    group.EvaluateTangent(params.data(), residuals.data(), jacobian.data());
    benchmark::DoNotOptimize(residuals.data());
    benchmark::ClobberMemory();
  }
  state.SetItemsProcessed(state.iterations() * kPoints);
}

BENCHMARK(BM_PointToSweepPlaneGroupTangent)->Name("PointToSweepPlaneGroup/tangent");

}  // namespace
}  // namespace autocal

BENCHMARK_MAIN();
