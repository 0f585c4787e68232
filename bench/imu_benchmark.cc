// IMU preintegration throughput (Release, one core): ns per IMU sample with covariance and
// bias Jacobians, without them, and for a re-integration after a bias change.

#include <benchmark/benchmark.h>

#include <cmath>

#include "autocal/sensors/imu_preintegration.h"

namespace autocal {
namespace sensors {
namespace {

constexpr int kSamples = 201;  // 1 s at 200 Hz
constexpr int64_t kPeriodNs = 5'000'000;

// A smoothly varying rate and specific force, as a car's IMU reports them.
ImuSamples MakeSamples() {
  ImuSamples samples(kSamples);
  for (int k = 0; k < kSamples; ++k) {
    const double t = 0.005 * k;
    samples[k].t_ns = k * kPeriodNs;
    samples[k].gyro_rad_s =
        Eigen::Vector3d(0.1 * std::sin(2.0 * t), 0.05 * std::cos(3.0 * t), 0.4 * std::sin(0.7 * t));
    samples[k].accel_m_s2 =
        Eigen::Vector3d(1.5 * std::cos(t), 0.8 * std::sin(1.3 * t), 9.81 + 0.2 * std::sin(5.0 * t));
  }
  return samples;
}

void Integrate(benchmark::State& state, bool covariance) {
  const ImuSamples samples = MakeSamples();
  PreintegrationOptions options;
  options.compute_covariance = covariance;
  for (auto _ : state) {
    ImuPreintegration pim(ImuNoise(), options);
    pim.Integrate(samples, 0, (kSamples - 1) * kPeriodNs);
    benchmark::DoNotOptimize(pim.delta_p());
  }
  state.SetItemsProcessed(state.iterations() * (kSamples - 1));
}

void BM_PreintegrateWithCovariance(benchmark::State& state) { Integrate(state, true); }
void BM_PreintegrateDeltasOnly(benchmark::State& state) { Integrate(state, false); }

void BM_Reintegrate(benchmark::State& state) {
  const ImuSamples samples = MakeSamples();
  ImuPreintegration pim{ImuNoise(), PreintegrationOptions()};
  pim.Integrate(samples, 0, (kSamples - 1) * kPeriodNs);
  double sign = 1.0;
  for (auto _ : state) {
    sign = -sign;
    pim.Reintegrate(Eigen::Vector3d::Constant(sign * 1e-3), Eigen::Vector3d::Constant(1e-2));
    benchmark::DoNotOptimize(pim.delta_p());
  }
  state.SetItemsProcessed(state.iterations() * (kSamples - 1));
}

void BM_SqrtInformation(benchmark::State& state) {
  const ImuSamples samples = MakeSamples();
  ImuPreintegration pim{ImuNoise(), PreintegrationOptions()};
  pim.Integrate(samples, 0, (kSamples - 1) * kPeriodNs);
  for (auto _ : state) benchmark::DoNotOptimize(pim.SqrtInformation());
}

BENCHMARK(BM_PreintegrateWithCovariance);
BENCHMARK(BM_PreintegrateDeltasOnly);
BENCHMARK(BM_Reintegrate);
BENCHMARK(BM_SqrtInformation);

}  // namespace
}  // namespace sensors
}  // namespace autocal

BENCHMARK_MAIN();
