// Wall time of autocal_calibrate's and autocal_estimate's pipelines on simulated urban logs
// (32 beams, every sensor, problems/urban_full.yaml), per stage. Goals: the 60 s log
// calibrated in at most 6 s on 2 cores; a 600 s log within 10x the 60 s time and 2 GB of peak
// memory; the online estimator at 5x real time or faster.
//
// Each duration is its own benchmark; run one per process for its peak memory (the counter
// is the process's maximum resident set so far):
//   build/bench/pipeline_benchmark --benchmark_filter='BM_CalibrateUrban/duration_s:60/'
// The log is simulated into $TMPDIR/autocal_pipeline_benchmark/urban_<s>s once and reused.
// The process keeps freed memory as autocal_calibrate and autocal_estimate do
// (tools/keep_freed_memory.h), so the figures are the tools' own.

#include <benchmark/benchmark.h>
#include <sys/resource.h>

#include <cstdlib>
#include <filesystem>
#include <string>

#include "autocal/io/dataset.h"
#include "autocal/io/problem_yaml.h"
#include "autocal/pipeline/offline_calibration.h"
#include "autocal/pipeline/online_estimation.h"
#include "autocal/sim/simulator.h"
#include "tool_benchmark_main.h"

namespace autocal {
namespace {

std::string UrbanLog(int duration_s) {
  const char* tmp = std::getenv("TMPDIR");
  const std::filesystem::path dir = std::filesystem::path(tmp != nullptr ? tmp : "/tmp") /
                                    "autocal_pipeline_benchmark" /
                                    ("urban_" + std::to_string(duration_s) + "s");
  if (!std::filesystem::exists(dir / "lidar.csv")) {
    sim::SimulationOptions options;
    options.scenario = sim::ScenarioType::kUrban;
    options.duration_s = duration_s;
    options.seed = 1;
    options.lidar.config.num_beams = 32;
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir.parent_path());
    sim::WriteDataset(sim::Simulator(options), dir.string());
  }
  return dir.string();
}

double PeakResidentMegabytes() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_maxrss) / 1024.0;  // ru_maxrss is in KiB on Linux
}

// run(dataset, problem) on the log of state.range(0) seconds, timed with reading the dataset.
template <typename Run>
auto TimeOnUrbanLog(benchmark::State& state, Run run) {
  const std::string log = UrbanLog(static_cast<int>(state.range(0)));
  const io::Problem problem = io::ReadProblemYaml(AUTOCAL_SOURCE_DIR "/problems/urban_full.yaml");
  decltype(run(io::Dataset(), problem)) result;
  for (auto _ : state) result = run(io::ReadDataset(log), problem);
  return result;
}

void BM_CalibrateUrban(benchmark::State& state) {
  const pipeline::OfflineCalibrationResult result = TimeOnUrbanLog(
      state,
      [](const io::Dataset& d, const io::Problem& p) { return pipeline::CalibrateDataset(d, p); });
  state.counters["loading_s"] = result.seconds_loading;
  state.counters["initialization_s"] = result.seconds_initialization;
  state.counters["solve_s"] = result.seconds_solve;
  state.counters["association_s"] = result.batch.seconds_association;
  state.counters["ceres_s"] = result.batch.seconds_solver;
  state.counters["uncertainty_s"] = result.seconds_uncertainty;
  state.counters["after_holding_s"] = result.seconds_after_holding;
  state.counters["peak_MB"] = PeakResidentMegabytes();
}
BENCHMARK(BM_CalibrateUrban)
    ->ArgName("duration_s")
    ->Arg(60)
    ->Arg(120)
    ->Arg(300)
    ->Arg(600)
    ->Unit(benchmark::kSecond)
    ->Iterations(1)
    ->UseRealTime();

// The online estimator over the whole log; real_time_factor is the log's length over the wall
// time.
void BM_EstimateUrban(benchmark::State& state) {
  const pipeline::OnlineEstimationResult result =
      TimeOnUrbanLog(state, [](const io::Dataset& d, const io::Problem& p) {
        return pipeline::EstimateDatasetOnline(d, p);
      });
  state.counters["initialization_s"] = result.seconds_initialization;
  state.counters["real_time_factor"] = static_cast<double>(state.range(0)) / result.seconds_total;
  state.counters["peak_MB"] = PeakResidentMegabytes();
}
BENCHMARK(BM_EstimateUrban)
    ->ArgName("duration_s")
    ->Arg(60)
    ->Unit(benchmark::kSecond)
    ->Iterations(1)
    ->UseRealTime();

}  // namespace
}  // namespace autocal

int main(int argc, char** argv) { return autocal::bench::RunBenchmarksAsTheToolsDo(argc, argv); }
