// The sliding-window estimator over a simulated urban drive (16 beams, all sensors): the
// distribution of the per-update time (one update per LiDAR sweep) and of the time spent
// marginalizing the oldest keyframe, as p50/p99 counters in milliseconds, with the median
// split of an update (association, problem build, solve), its solver iterations, plane
// lookups and the point-to-plane residuals in the window; the thread CPU time of an update
// (robust to other load on the machine) and the median step of the calibration per update.
// BM_PlaneLookup times the association's inner step, a plane lookup, on its own.
#include <benchmark/benchmark.h>
#include <time.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <memory>
#include <numeric>
#include <string>
#include <tuple>
#include <vector>

#include "autocal/common/time.h"
#include "autocal/common/units.h"
#include "autocal/estimation/sliding_window.h"
#include "autocal/geometry/so3.h"
#include "autocal/lidar/plane_map.h"
#include "autocal/lidar/voxel_grid.h"
#include "autocal/sim/simulator.h"
#include "estimation/lower_gram.h"

namespace autocal {
namespace {

struct Log {
  sim::SimulationOptions options;
  std::unique_ptr<sim::Simulator> simulator;
  sim::SimulatedLog data;
  // (arrival time, kind, index) in arrival order; kind 0 IMU, 1 wheel, 2 GNSS, 3 sweep.
  std::vector<std::tuple<int64_t, int, size_t>> events;
};

const Log& UrbanLog() {
  static const Log* log = [] {
    auto* l = new Log;
    l->options.scenario = sim::ScenarioType::kUrban;
    l->options.duration_s = 20.0;
    l->options.seed = 11;
    l->options.lidar.config.num_beams = 16;
    l->simulator = std::make_unique<sim::Simulator>(l->options);
    l->data = sim::Simulate(*l->simulator);
    const sim::SimulatedLog& d = l->data;
    for (size_t i = 0; i < d.imu.samples.size(); ++i)
      l->events.emplace_back(d.imu.samples[i].t_ns, 0, i);
    for (size_t i = 0; i < d.wheel.size(); ++i) l->events.emplace_back(d.wheel[i].t_ns, 1, i);
    for (size_t i = 0; i < d.gnss.fixes.size(); ++i)
      l->events.emplace_back(d.gnss.fixes[i].t_ns, 2, i);
    for (size_t i = 0; i < d.sweeps.size(); ++i) {
      l->events.emplace_back(d.sweeps[i].t_ns + SecondsToNs(d.sweeps[i].cloud.time_s.maxCoeff()), 3,
                             i);
    }
    std::stable_sort(l->events.begin(), l->events.end(),
                     [](const auto& a, const auto& b) { return std::get<0>(a) < std::get<0>(b); });
    return l;
  }();
  return *log;
}

// CPU time of the calling thread: the updates run on it (num_threads = 1), and unlike the
// wall clock it does not count the time other processes on a shared machine take.
double ThreadCpuSeconds() {
  timespec t;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

double Percentile(std::vector<double> values, double q) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  const size_t i = static_cast<size_t>(q * static_cast<double>(values.size() - 1) + 0.5);
  return values[i];
}

// The split of a set of updates: total, association, build and solve (ms), plane lookups.
struct UpdateSplit {
  std::vector<double> update_ms, association_ms, build_ms, solve_ms, lookups;

  void Add(const estimation::SlidingWindowUpdateTiming& timing) {
    update_ms.push_back(1e3 * timing.total_s);
    association_ms.push_back(1e3 * timing.association_s);
    build_ms.push_back(1e3 * timing.build_s);
    solve_ms.push_back(1e3 * timing.solve_s);
    lookups.push_back(timing.plane_lookups);
  }
  // Counters `prefix`update_p50_ms, ..._p99_ms, association_p50_ms, build_p50_ms,
  // solve_p50_ms and lookups_p50.
  void Report(const std::string& prefix, benchmark::State* bench) const {
    bench->counters[prefix + "update_p50_ms"] = Percentile(update_ms, 0.5);
    bench->counters[prefix + "update_p99_ms"] = Percentile(update_ms, 0.99);
    bench->counters[prefix + "association_p50_ms"] = Percentile(association_ms, 0.5);
    bench->counters[prefix + "build_p50_ms"] = Percentile(build_ms, 0.5);
    bench->counters[prefix + "solve_p50_ms"] = Percentile(solve_ms, 0.5);
    bench->counters[prefix + "lookups_p50"] = Percentile(lookups, 0.5);
  }
};

void BM_SlidingWindowUrban(benchmark::State& bench) {
  const Log& log = UrbanLog();
  const io::SensorsConfig config = log.simulator->sensors_config();
  estimation::SlidingWindowOptions options;
  options.imu = config.imu;
  options.wheel = *config.wheel;
  options.enu_origin_lla =
      Eigen::Vector3d(log.options.gnss.origin_lat_deg, log.options.gnss.origin_lon_deg,
                      log.options.gnss.origin_alt_m);
  options.pairing.max_residuals_per_sweep = static_cast<int>(bench.range(0));
  options.pairing.residual_voxel_m = 0.01 * static_cast<double>(bench.range(2));
  if (bench.range(1) == 0) {  // no reuse: every keyframe re-paired, every map rebuilt
    options.window_pairing.reassociation_tolerance_m = 0.0;
    options.window_pairing.map_rebuild_tolerance_m = 0.0;
  }
  // The initial state: the truth at the first IMU sample (the drive starts at rest).
  const io::TrajectorySample& first = log.data.imu.truth.front();
  estimation::SlidingWindowState initial;
  initial.t_ns = first.t_ns;
  initial.q_W_I = first.T_W_I.q;
  initial.p_W_I = first.T_W_I.p;
  initial.v_W_I = first.v_W_I;
  initial.b_g = log.data.imu.gyro_bias.front();
  initial.b_a = log.data.imu.accel_bias.front();

  std::vector<double> update_cpu_ms, marginalization_ms, points, iterations, passes,
      rotation_step_deg, translation_step_mm, offset_step_ms;
  // Every update, and those whose extrinsic had settled (the settled partner walk: points try
  // settled_partner_count partners).
  UpdateSplit all, settled;
  double q_I_L_error_deg = 0.0;
  for (auto _ : bench) {
    estimation::SlidingWindowEstimator estimator(options, log.simulator->nominal_calibration(),
                                                 initial);
    int64_t updates = 0;
    sensors::Calibration previous = estimator.calibration();
    for (const auto& [t, kind, i] : log.events) {
      const double cpu_start_s = ThreadCpuSeconds();
      switch (kind) {
        case 0:
          estimator.AddImu(log.data.imu.samples[i]);
          break;
        case 1:
          estimator.AddWheel(log.data.wheel[i]);
          break;
        case 2:
          estimator.AddGnss(log.data.gnss.fixes[i]);
          break;
        default:
          estimator.AddSweep(log.data.sweeps[i]);
          break;
      }
      if (estimator.counters().updates == updates) continue;
      updates = estimator.counters().updates;
      const estimation::SlidingWindowUpdateTiming& timing = estimator.last_update_timing();
      all.Add(timing);
      if (timing.extrinsic_settled) settled.Add(timing);
      update_cpu_ms.push_back(1e3 * (ThreadCpuSeconds() - cpu_start_s));
      const sensors::Calibration& c = estimator.calibration();
      rotation_step_deg.push_back(geometry::AngularDistance(c.q_I_L, previous.q_I_L) * kRadToDeg);
      translation_step_mm.push_back(1e3 * (c.p_I_L - previous.p_I_L).norm());
      offset_step_ms.push_back(
          1e3 * std::abs(c.time_offset_lidar_imu_s - previous.time_offset_lidar_imu_s));
      previous = c;
      points.push_back(estimator.last_associated_points());
      iterations.push_back(timing.solver_iterations);
      passes.push_back(timing.solver_passes);
      if (timing.marginalization_s > 0.0)
        marginalization_ms.push_back(1e3 * timing.marginalization_s);
    }
    q_I_L_error_deg = geometry::AngularDistance(estimator.calibration().q_I_L,
                                                log.simulator->true_calibration().q_I_L) *
                      kRadToDeg;
  }
  bench.counters["updates"] = static_cast<double>(all.update_ms.size());
  all.Report("", &bench);
  bench.counters["update_cpu_p50_ms"] = Percentile(update_cpu_ms, 0.5);
  bench.counters["update_cpu_p99_ms"] = Percentile(update_cpu_ms, 0.99);
  bench.counters["rotation_step_p50_deg"] = Percentile(rotation_step_deg, 0.5);
  bench.counters["translation_step_p50_mm"] = Percentile(translation_step_mm, 0.5);
  bench.counters["offset_step_p50_ms"] = Percentile(offset_step_ms, 0.5);
  bench.counters["points_p50"] = Percentile(points, 0.5);  // paired residual points, window
  bench.counters["points_per_sweep_p50"] = Percentile(points, 0.5) / options.window_size;
  bench.counters["iterations_p50"] = Percentile(iterations, 0.5);
  bench.counters["passes_mean"] =
      passes.empty() ? 0.0 : std::accumulate(passes.begin(), passes.end(), 0.0) / passes.size();
  bench.counters["marginalization_p50_ms"] = Percentile(marginalization_ms, 0.5);
  bench.counters["marginalization_p99_ms"] = Percentile(marginalization_ms, 0.99);
  bench.counters["settled_share"] =
      static_cast<double>(settled.update_ms.size()) / static_cast<double>(all.update_ms.size());
  settled.Report("settled_", &bench);
  bench.counters["q_I_L_error_end_deg"] = q_I_L_error_deg;
}
// Arguments: residual points per sweep (candidates: about a third to a half pair with a
// plane); reuse between updates (1: the default tolerances, 0: every keyframe re-paired and
// every plane map rebuilt at every update); the residual voxel in cm (60 the default; 35 with
// up to 6000 candidates pairs about 2000 points per sweep).
BENCHMARK(BM_SlidingWindowUrban)
    ->ArgNames({"points", "reuse", "voxel_cm"})
    ->Args({500, 1, 60})
    ->Args({2000, 0, 60})
    ->Args({2000, 1, 60})
    ->Args({6000, 1, 35})
    ->Iterations(1)
    ->Unit(benchmark::kSecond);

// The association's inner step alone: the residual points of one sweep looked up in the plane
// map of another (PlaneMap::FindPlane), placed with the true relative pose of the two sweeps'
// first points (the motion within the sweeps left out: the mix of planes and failures is what
// matters here). Time per lookup, with the share that finds a plane. Arguments: the second
// sweep's offset from the first, in sweeps.
void BM_PlaneLookup(benchmark::State& bench) {
  const Log& log = UrbanLog();
  const sim::Simulator& simulator = *log.simulator;
  const sensors::Calibration& c = simulator.true_calibration();
  const geometry::Pose3d T_I_L(c.q_I_L, c.p_I_L);
  const auto T_W_L = [&](const lidar::LidarSweep& sweep) {
    return simulator.ImuPoseAt(simulator.TimeOf(sweep.t_ns) + c.time_offset_lidar_imu_s) * T_I_L;
  };
  // The window's defaults: residual points one per 0.6 m voxel (at most 2000, evenly
  // spread), map points one per 0.3 m voxel, in a map of the default options.
  const lidar::LidarSweep& residual_sweep = log.data.sweeps[100];
  const lidar::LidarSweep& map_sweep = log.data.sweeps[static_cast<size_t>(100 + bench.range(0))];
  const lidar::PlaneMap map(lidar::VoxelDownsample(map_sweep.cloud, 0.3).points);
  const Eigen::Matrix3Xd residual = lidar::VoxelDownsample(residual_sweep.cloud, 0.6).points;
  const geometry::Pose3d T_Lj_Lk = T_W_L(map_sweep).Inverse() * T_W_L(residual_sweep);
  const Eigen::Index count = std::min<Eigen::Index>(2000, residual.cols());
  Eigen::Matrix3Xd queries(3, count);
  for (Eigen::Index i = 0; i < count; ++i) {
    queries.col(i) = T_Lj_Lk * Eigen::Vector3d(residual.col(i * residual.cols() / count));
  }
  int64_t found = 0;
  for (auto _ : bench) {
    found = 0;
    geometry::Plane plane;
    for (Eigen::Index i = 0; i < count; ++i) found += map.FindPlane(queries.col(i), &plane);
    benchmark::DoNotOptimize(found);
  }
  bench.SetItemsProcessed(bench.iterations() * count);
  bench.counters["ns_per_lookup"] =
      benchmark::Counter(static_cast<double>(bench.iterations() * count),
                         benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
  bench.counters["found_share"] = static_cast<double>(found) / static_cast<double>(count);
  bench.counters["map_points"] = static_cast<double>(map.size());
}
BENCHMARK(BM_PlaneLookup)->ArgName("offset")->Arg(-5)->Arg(5)->Unit(benchmark::kMicrosecond);

// A compressed point group's J_T^T J_T and J_T^T r (Eq. W3): 2000 points in the 22 tangent
// columns, column-major, by the window's kernel (simd 1: AVX2 where the processor has it; 0:
// the plain loops, the same bits) and by Eigen's blocked rank update, which it replaced.
constexpr int kGramRows = 2000;
constexpr int kGramColumns = 22;

void BM_LowerGram(benchmark::State& bench) {
  const Eigen::MatrixXd J = Eigen::MatrixXd::Random(kGramRows, kGramColumns);
  const Eigen::VectorXd r = Eigen::VectorXd::Random(kGramRows);
  Eigen::MatrixXd gram(kGramColumns, kGramColumns);
  Eigen::VectorXd gradient(kGramColumns);
  for (auto _ : bench) {
    estimation::internal::LowerGramAndGradient(J.data(), kGramRows, kGramColumns, r.data(),
                                               gram.data(), gradient.data(), bench.range(0) != 0);
    benchmark::DoNotOptimize(gram.data());
    benchmark::DoNotOptimize(gradient.data());
  }
  bench.SetItemsProcessed(bench.iterations() * kGramRows);
}
BENCHMARK(BM_LowerGram)->ArgName("simd")->Arg(1)->Arg(0);

void BM_LowerGramEigen(benchmark::State& bench) {
  const Eigen::Matrix<double, Eigen::Dynamic, kGramColumns> J =
      Eigen::Matrix<double, Eigen::Dynamic, kGramColumns>::Random(kGramRows, kGramColumns);
  const Eigen::VectorXd r = Eigen::VectorXd::Random(kGramRows);
  Eigen::Matrix<double, kGramColumns, kGramColumns> gram;
  Eigen::Matrix<double, kGramColumns, 1> gradient;
  for (auto _ : bench) {
    gram.setZero();
    gram.selfadjointView<Eigen::Lower>().rankUpdate(J.transpose());
    gradient = J.transpose() * r;
    benchmark::DoNotOptimize(gram.data());
    benchmark::DoNotOptimize(gradient.data());
  }
  bench.SetItemsProcessed(bench.iterations() * kGramRows);
}
BENCHMARK(BM_LowerGramEigen);

}  // namespace
}  // namespace autocal

BENCHMARK_MAIN();
