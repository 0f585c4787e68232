// Cost of one Evaluate with all Jacobians (Release, one core): the analytic factors and
// their autodiff twins, and the wheel and GNSS rows carried to a sample on a clock of its own
// (Eq. K16, estimation/time_offset_factors.h), which exist only as autodiff.

#include <benchmark/benchmark.h>

#include <cmath>
#include <memory>
#include <vector>

#include "autocal/factors/gnss_factor.h"
#include "autocal/factors/imu_factor.h"
#include "autocal/factors/wheel_factor.h"
#include "autocal/geometry/so3.h"
#include "estimation/time_offset_factors.h"

namespace autocal {
namespace factors {
namespace {

// Parameter and Jacobian storage for one evaluation of a cost function.
class Evaluation {
 public:
  Evaluation(const ceres::CostFunction& cost, std::vector<double*> parameters)
      : parameters_(std::move(parameters)), residuals_(cost.num_residuals()) {
    for (int size : cost.parameter_block_sizes()) {
      storage_.emplace_back(static_cast<size_t>(size * cost.num_residuals()));
    }
    for (auto& s : storage_) jacobians_.push_back(s.data());
  }
  bool Run(const ceres::CostFunction& cost, bool with_jacobians) {
    return cost.Evaluate(parameters_.data(), residuals_.data(),
                         with_jacobians ? jacobians_.data() : nullptr);
  }

 private:
  std::vector<double*> parameters_;
  std::vector<double> residuals_;
  std::vector<std::vector<double>> storage_;
  std::vector<double*> jacobians_;
};

struct ImuBlocks {
  Eigen::Quaterniond q_i = geometry::Exp(Eigen::Vector3d(0.3, -0.2, 1.0));
  Eigen::Quaterniond q_j = geometry::Exp(Eigen::Vector3d(0.35, -0.18, 1.1));
  Eigen::Vector3d p_i{1.0, 2.0, 0.5}, p_j{2.0, 2.5, 0.4}, v_i{8.0, 1.0, 0.0}, v_j{8.2, 1.1, 0.0};
  Eigen::Vector3d bg_i{1e-3, -2e-3, 5e-4}, ba_i{0.02, -0.01, 0.03}, bg_j = bg_i, ba_j = ba_i;
  std::vector<double*> Pointers() {
    return {q_i.coeffs().data(), p_i.data(), v_i.data(), bg_i.data(), ba_i.data(),
            q_j.coeffs().data(), p_j.data(), v_j.data(), bg_j.data(), ba_j.data()};
  }
};

sensors::ImuPreintegration MakePreintegration() {
  sensors::ImuSamples samples(21);
  for (int k = 0; k < 21; ++k) {
    samples[k].t_ns = k * 5'000'000;
    samples[k].gyro_rad_s = Eigen::Vector3d(0.1, 0.05 * k, 0.4);
    samples[k].accel_m_s2 = Eigen::Vector3d(1.5, 0.2, 9.81);
  }
  sensors::ImuPreintegration pim{sensors::ImuNoise(), sensors::PreintegrationOptions()};
  pim.Integrate(samples, 0, 100'000'000);
  return pim;
}

void RunImu(benchmark::State& state, const ceres::CostFunction& cost, bool jacobians) {
  ImuBlocks blocks;
  Evaluation evaluation(cost, blocks.Pointers());
  for (auto _ : state) benchmark::DoNotOptimize(evaluation.Run(cost, jacobians));
}

void BM_ImuFactorAnalytic(benchmark::State& state) {
  const ImuFactor cost(MakePreintegration());
  RunImu(state, cost, true);
}
void BM_ImuFactorAutodiff(benchmark::State& state) {
  const std::unique_ptr<ceres::CostFunction> cost(
      ImuResidual::CreateAutoDiff(MakePreintegration()));
  RunImu(state, *cost, true);
}
void BM_ImuFactorResidualOnly(benchmark::State& state) {
  const ImuFactor cost(MakePreintegration());
  RunImu(state, cost, false);
}

struct WheelBlocks {
  Eigen::Quaterniond q_W_I = geometry::Exp(Eigen::Vector3d(0.02, -0.01, 1.2));
  Eigen::Vector3d v_W_I{9.0, 4.0, 0.1}, b_g{1e-3, 2e-3, -1e-3};
  Eigen::Quaterniond q_I_V = geometry::Exp(Eigen::Vector3d(0.01, 0.02, 0.0));
  Eigen::Vector3d p_I_V{-1.2, 0.0, -0.4};
  double r_l = 0.33, r_r = 0.331, b = 1.6;
  std::vector<double*> Pointers() {
    return {q_W_I.coeffs().data(), v_W_I.data(), b_g.data(), q_I_V.coeffs().data(),
            p_I_V.data(),          &r_l,         &r_r,       &b};
  }
};

WheelMeasurement MakeWheel() {
  WheelMeasurement m;
  m.left_rad_s = 29.5;
  m.right_rad_s = 30.5;
  m.gyro_rad_s = Eigen::Vector3d(0.01, -0.02, 0.2);
  return m;
}

void RunWheel(benchmark::State& state, const ceres::CostFunction& cost) {
  WheelBlocks blocks;
  Evaluation evaluation(cost, blocks.Pointers());
  for (auto _ : state) benchmark::DoNotOptimize(evaluation.Run(cost, true));
}

void BM_WheelFactorAnalytic(benchmark::State& state) {
  const WheelFactor cost(MakeWheel(), WheelFactorOptions());
  RunWheel(state, cost);
}
void BM_WheelFactorAutodiff(benchmark::State& state) {
  const std::unique_ptr<ceres::CostFunction> cost(
      WheelResidual::CreateAutoDiff(MakeWheel(), WheelFactorOptions()));
  RunWheel(state, *cost);
}

GnssMeasurement MakeGnss() {
  GnssMeasurement m;
  m.p_W_A = Eigen::Vector3d(10.0, 20.0, 1.5);
  m.sigma_enu_m = Eigen::Vector3d(0.02, 0.02, 0.05);
  return m;
}

void RunGnss(benchmark::State& state, const ceres::CostFunction& cost) {
  Eigen::Quaterniond q = geometry::Exp(Eigen::Vector3d(0.02, -0.01, 1.2));
  Eigen::Vector3d p(9.8, 19.9, 0.2), p_I_A(0.5, 0.1, 1.3);
  Evaluation evaluation(cost, {q.coeffs().data(), p.data(), p_I_A.data()});
  for (auto _ : state) benchmark::DoNotOptimize(evaluation.Run(cost, true));
}

void BM_GnssFactorAnalytic(benchmark::State& state) {
  const GnssFactor cost(MakeGnss());
  RunGnss(state, cost);
}
void BM_GnssFactorAutodiff(benchmark::State& state) {
  const std::unique_ptr<ceres::CostFunction> cost(GnssResidual::CreateAutoDiff(MakeGnss()));
  RunGnss(state, *cost);
}

// The IMU around a keyframe and the carried rows' extra blocks (b_a, the clock offset).
estimation::internal::ImuAroundKeyframe MakeImuAround() {
  estimation::internal::ImuAroundKeyframe imu;
  imu.gyro_rad_s = Eigen::Vector3d(0.01, -0.02, 0.2);
  imu.gyro_slope_rad_s2 = Eigen::Vector3d(0.001, 0.002, -0.05);
  imu.accel_m_s2 = Eigen::Vector3d(0.8, 0.3, 9.81);
  imu.g_W = Eigen::Vector3d(0.0, 0.0, -9.80665);
  return imu;
}
constexpr int64_t kKeyframeNs = 1'000'000'000;
constexpr int64_t kSampleNs = kKeyframeNs + 37'000'000;  // 37 ms after the keyframe

void BM_ShiftedGnssResidual(benchmark::State& state) {
  const std::unique_ptr<ceres::CostFunction> cost(estimation::internal::ShiftedGnssResidual::Create(
      MakeGnss(), kSampleNs, kKeyframeNs, MakeImuAround()));
  Eigen::Quaterniond q = geometry::Exp(Eigen::Vector3d(0.02, -0.01, 1.2));
  Eigen::Vector3d p(9.8, 19.9, 0.2), v(9.0, 4.0, 0.1), b_g(1e-3, 2e-3, -1e-3),
      b_a(0.02, -0.01, 0.03), p_I_A(0.5, 0.1, 1.3);
  double offset_s = 0.004;
  Evaluation evaluation(*cost, {q.coeffs().data(), p.data(), v.data(), b_g.data(), b_a.data(),
                                p_I_A.data(), &offset_s});
  for (auto _ : state) benchmark::DoNotOptimize(evaluation.Run(*cost, true));
}

void BM_ShiftedWheelResidual(benchmark::State& state) {
  estimation::internal::PairedWheelSample sample;
  sample.values = Eigen::Vector2d(29.5, 30.5);
  sample.t_ns = kSampleNs;
  sample.gyro_rad_s = MakeWheel().gyro_rad_s;
  const std::unique_ptr<ceres::CostFunction> cost(
      estimation::internal::ShiftedWheelResidual::Create(sample, kKeyframeNs, MakeImuAround(),
                                                         estimation::internal::ShiftedWheelForm(),
                                                         WheelFactorOptions()));
  WheelBlocks blocks;
  Eigen::Vector3d b_a(0.02, -0.01, 0.03);
  double offset_s = 0.004;
  Evaluation evaluation(
      *cost, {blocks.q_W_I.coeffs().data(), blocks.v_W_I.data(), blocks.b_g.data(), b_a.data(),
              blocks.q_I_V.coeffs().data(), blocks.p_I_V.data(), &blocks.r_l, &blocks.r_r,
              &blocks.b, &offset_s});
  for (auto _ : state) benchmark::DoNotOptimize(evaluation.Run(*cost, true));
}

BENCHMARK(BM_ImuFactorAnalytic);
BENCHMARK(BM_ImuFactorAutodiff);
BENCHMARK(BM_ImuFactorResidualOnly);
BENCHMARK(BM_WheelFactorAnalytic);
BENCHMARK(BM_WheelFactorAutodiff);
BENCHMARK(BM_GnssFactorAnalytic);
BENCHMARK(BM_GnssFactorAutodiff);
BENCHMARK(BM_ShiftedGnssResidual);
BENCHMARK(BM_ShiftedWheelResidual);

}  // namespace
}  // namespace factors
}  // namespace autocal

BENCHMARK_MAIN();
