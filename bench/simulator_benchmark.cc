// Speed of the simulator. Goal: a 60 s urban log with a 32-beam LiDAR generated in memory
// in under 10 s on one core (BM_UrbanLog60s32Beams). The process keeps freed memory as
// autocal_simulate does (tools/keep_freed_memory.h), so the figures are the tool's own.

#include <benchmark/benchmark.h>

#include <cstdlib>
#include <filesystem>

#include "autocal/sim/simulator.h"
#include "tool_benchmark_main.h"

namespace autocal {
namespace sim {
namespace {

SimulationOptions Options(ScenarioType scenario, double duration_s, int beams) {
  SimulationOptions options;
  options.scenario = scenario;
  options.duration_s = duration_s;
  options.lidar.config.num_beams = beams;
  return options;
}

// Every sensor of the log, sweeps generated one at a time and dropped (as WriteDataset does).
void GenerateLog(const SimulationOptions& options, benchmark::State& state) {
  int64_t points = 0;
  for (auto _ : state) {
    const Simulator simulator(options);
    benchmark::DoNotOptimize(simulator.GenerateImu());
    benchmark::DoNotOptimize(simulator.GenerateWheel());
    benchmark::DoNotOptimize(simulator.GenerateGnss());
    for (int k = 0; k < simulator.num_sweeps(); ++k) {
      points += simulator.GenerateSweep(k).cloud.size();
    }
  }
  state.counters["points"] = benchmark::Counter(static_cast<double>(points) / state.iterations());
}

void BM_UrbanLog60s32Beams(benchmark::State& state) {
  GenerateLog(Options(ScenarioType::kUrban, 60.0, 32), state);
}
BENCHMARK(BM_UrbanLog60s32Beams)->Unit(benchmark::kSecond)->Iterations(2);

void BM_HighwayLog60s32Beams(benchmark::State& state) {
  GenerateLog(Options(ScenarioType::kHighway, 60.0, 32), state);
}
BENCHMARK(BM_HighwayLog60s32Beams)->Unit(benchmark::kSecond)->Iterations(2);

// The 60 s urban log written as a dataset (PLY sweeps and CSV files) into $TMPDIR, its
// sweeps generated on 1 and 2 threads (WriteDataset).
void BM_WriteUrbanLog60s32Beams(benchmark::State& state) {
  const char* tmp = std::getenv("TMPDIR");
  const std::filesystem::path dir =
      std::filesystem::path(tmp != nullptr ? tmp : "/tmp") / "autocal_simulator_benchmark";
  const Simulator simulator(Options(ScenarioType::kUrban, 60.0, 32));
  for (auto _ : state) {
    std::filesystem::remove_all(dir);
    WriteDataset(simulator, dir.string(), static_cast<int>(state.range(0)));
  }
  std::filesystem::remove_all(dir);
}
BENCHMARK(BM_WriteUrbanLog60s32Beams)
    ->ArgName("threads")
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kSecond)
    ->Iterations(1)
    ->UseRealTime();

// One sweep (900 columns) for 16, 32 and 64 beams.
void BM_Sweep(benchmark::State& state) {
  const Simulator simulator(Options(ScenarioType::kUrban, 20.0, static_cast<int>(state.range(0))));
  int k = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(simulator.GenerateSweep(k));
    k = (k + 1) % simulator.num_sweeps();
  }
}
BENCHMARK(BM_Sweep)->Arg(16)->Arg(32)->Arg(64)->Unit(benchmark::kMillisecond);

// The exact kinematics behind every IMU sample.
void BM_ImuKinematics(benchmark::State& state) {
  const Simulator simulator(Options(ScenarioType::kUrban, 60.0, 16));
  const VehicleTrajectory& trajectory = *simulator.scenario().trajectory;
  double t = 0.0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(trajectory.StateAt(t));
    t = t < 60.0 ? t + 0.005 : 0.0;
  }
}
BENCHMARK(BM_ImuKinematics);

}  // namespace
}  // namespace sim
}  // namespace autocal

int main(int argc, char** argv) { return autocal::bench::RunBenchmarksAsTheToolsDo(argc, argv); }
