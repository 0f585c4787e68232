// LiDAR module speed on the real scan pair (../shared/data/lidar_scan_pair, or
// $AUTOCAL_SHARED_DIR/data/lidar_scan_pair): voxel downsampling, k-d tree build and queries,
// target normals, and full point-to-plane registration at 0.25 m voxels. Single-threaded.
// nanoflann, the k-d tree the library used before its own, is measured alongside. The
// odometry's local voxel map is timed on synthetic planes along each axis.

#include <benchmark/benchmark.h>

#include <cstdlib>
#include <filesystem>
#include <limits>
#include <nanoflann.hpp>
#include <random>
#include <string>
#include <vector>

#include "autocal/io/point_cloud_file.h"
#include "autocal/lidar/icp.h"
#include "autocal/lidar/kd_tree.h"
#include "autocal/lidar/local_voxel_map.h"
#include "autocal/lidar/normals.h"
#include "autocal/lidar/registration.h"
#include "autocal/lidar/voxel_grid.h"

namespace {

using autocal::lidar::PointCloud;

std::filesystem::path ScanPairDir() {
  if (const char* env = std::getenv("AUTOCAL_SHARED_DIR")) {
    return std::filesystem::path(env) / "data" / "lidar_scan_pair";
  }
  // bench/lidar_benchmark.cc -> <project>/../shared/data/lidar_scan_pair
  return std::filesystem::path(__FILE__).parent_path().parent_path().parent_path() / "shared" /
         "data" / "lidar_scan_pair";
}

struct ScanPair {
  PointCloud source;
  PointCloud target;
  bool loaded = false;
};

const ScanPair& LoadPair() {
  static const ScanPair pair = [] {
    ScanPair p;
    const std::filesystem::path dir = ScanPairDir();
    if (!std::filesystem::exists(dir / "source.ply")) return p;
    p.source = autocal::io::ReadPointCloudFile((dir / "source.ply").string());
    p.target = autocal::io::ReadPointCloudFile((dir / "target.ply").string());
    p.loaded = true;
    return p;
  }();
  return pair;
}

#define REQUIRE_PAIR(state)                                                            \
  const ScanPair& pair = LoadPair();                                                   \
  if (!pair.loaded) {                                                                  \
    state.SkipWithError(("scan pair not found at " + ScanPairDir().string()).c_str()); \
    return;                                                                            \
  }

void BM_VoxelDownsample(benchmark::State& state) {
  REQUIRE_PAIR(state);
  const double voxel_m = state.range(0) / 100.0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(autocal::lidar::VoxelDownsample(pair.source, voxel_m));
  }
  state.counters["points_in"] = static_cast<double>(pair.source.size());
}
BENCHMARK(BM_VoxelDownsample)->Arg(10)->Arg(25)->Unit(benchmark::kMillisecond);

void BM_KdTreeBuildFullScan(benchmark::State& state) {
  REQUIRE_PAIR(state);
  for (auto _ : state) {
    autocal::lidar::KdTree tree(pair.source.points);
    benchmark::DoNotOptimize(tree.size());
  }
  state.counters["points"] = static_cast<double>(pair.source.size());
}
BENCHMARK(BM_KdTreeBuildFullScan)->Unit(benchmark::kMillisecond);

// Query workload on the full-scan tree: 10,000 points of the target scan (the other sweep,
// so queries lie near but not on the indexed points), drawn with a fixed seed.
constexpr int kNumQueries = 10000;

Eigen::Matrix3Xd QueryPoints(const PointCloud& cloud) {
  std::mt19937 rng(7);
  std::uniform_int_distribution<Eigen::Index> pick(0, cloud.points.cols() - 1);
  Eigen::Matrix3Xd queries(3, kNumQueries);
  for (int i = 0; i < kNumQueries; ++i) queries.col(i) = cloud.points.col(pick(rng));
  return queries;
}

void BM_KdTreeKnnFullScan(benchmark::State& state) {
  REQUIRE_PAIR(state);
  const autocal::lidar::KdTree tree(pair.source.points);
  const Eigen::Matrix3Xd queries = QueryPoints(pair.target);
  const int k = static_cast<int>(state.range(0));
  std::vector<autocal::lidar::Neighbor> neighbors(static_cast<size_t>(k));
  for (auto _ : state) {
    double sum_m2 = 0.0;
    for (int i = 0; i < kNumQueries; ++i) {
      tree.Knn(queries.col(i), k, neighbors.data());
      sum_m2 += neighbors[static_cast<size_t>(k - 1)].squared_distance_m2;
    }
    benchmark::DoNotOptimize(sum_m2);
  }
  state.counters["queries"] = kNumQueries;
}
BENCHMARK(BM_KdTreeKnnFullScan)->Arg(5)->Arg(10)->Unit(benchmark::kMillisecond);

// The same build and k-NN workload through nanoflann 1.4 (leaf 16, as the library used it
// before its own tree): the peer the k-d tree is measured against.
struct NanoflannAdaptor {
  const Eigen::Matrix3Xd* points = nullptr;
  size_t kdtree_get_point_count() const { return static_cast<size_t>(points->cols()); }
  double kdtree_get_pt(size_t index, size_t dim) const {
    return (*points)(static_cast<Eigen::Index>(dim), static_cast<Eigen::Index>(index));
  }
  template <class BoundingBox>
  bool kdtree_get_bbox(BoundingBox& /*bbox*/) const {
    return false;
  }
};
using NanoflannIndex =
    nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, NanoflannAdaptor>,
                                        NanoflannAdaptor, 3, uint32_t>;

void BM_NanoflannBuildFullScan(benchmark::State& state) {
  REQUIRE_PAIR(state);
  for (auto _ : state) {
    const Eigen::Matrix3Xd points = pair.source.points;  // the copy KdTree makes too
    const NanoflannAdaptor adaptor{&points};
    NanoflannIndex index(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(16));
    benchmark::DoNotOptimize(index.root_node);
  }
}
BENCHMARK(BM_NanoflannBuildFullScan)->Unit(benchmark::kMillisecond);

void BM_NanoflannKnnFullScan(benchmark::State& state) {
  REQUIRE_PAIR(state);
  const NanoflannAdaptor adaptor{&pair.source.points};
  const NanoflannIndex index(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(16));
  const Eigen::Matrix3Xd queries = QueryPoints(pair.target);
  const size_t k = static_cast<size_t>(state.range(0));
  std::vector<uint32_t> indices(k);
  std::vector<double> distances(k);
  for (auto _ : state) {
    double sum_m2 = 0.0;
    for (int i = 0; i < kNumQueries; ++i) {
      nanoflann::KNNResultSet<double, uint32_t, size_t> result(k);
      result.init(indices.data(), distances.data());
      index.findNeighbors(result, queries.col(i).data(), nanoflann::SearchParams());
      sum_m2 += distances[k - 1];
    }
    benchmark::DoNotOptimize(sum_m2);
  }
  state.counters["queries"] = kNumQueries;
}
BENCHMARK(BM_NanoflannKnnFullScan)->Arg(5)->Arg(10)->Unit(benchmark::kMillisecond);

// Nearest with no bound (argument 0) and with the ICP default bound of 1 m (argument 100, cm).
void BM_KdTreeNearestFullScan(benchmark::State& state) {
  REQUIRE_PAIR(state);
  const autocal::lidar::KdTree tree(pair.source.points);
  const Eigen::Matrix3Xd queries = QueryPoints(pair.target);
  const double bound_m =
      state.range(0) == 0 ? std::numeric_limits<double>::infinity() : state.range(0) / 100.0;
  int found = 0;
  for (auto _ : state) {
    found = 0;
    autocal::lidar::Neighbor nearest;
    for (int i = 0; i < kNumQueries; ++i) found += tree.Nearest(queries.col(i), bound_m, &nearest);
    benchmark::DoNotOptimize(found);
  }
  state.counters["found"] = found;
}
BENCHMARK(BM_KdTreeNearestFullScan)->Arg(0)->Arg(100)->Unit(benchmark::kMillisecond);

void BM_KdTreeRadiusFullScan(benchmark::State& state) {
  REQUIRE_PAIR(state);
  const autocal::lidar::KdTree tree(pair.source.points);
  const Eigen::Matrix3Xd queries = QueryPoints(pair.target);
  const double radius_m = state.range(0) / 100.0;
  std::vector<autocal::lidar::Neighbor> neighbors;
  size_t total = 0;
  for (auto _ : state) {
    total = 0;
    for (int i = 0; i < kNumQueries; ++i) {
      tree.RadiusSearch(queries.col(i), radius_m, &neighbors);
      total += neighbors.size();
    }
    benchmark::DoNotOptimize(total);
  }
  state.counters["mean_found"] = static_cast<double>(total) / kNumQueries;
}
BENCHMARK(BM_KdTreeRadiusFullScan)->Arg(50)->Unit(benchmark::kMillisecond);

void BM_TargetPreparation(benchmark::State& state) {
  REQUIRE_PAIR(state);
  const Eigen::Matrix3Xd target = autocal::lidar::VoxelDownsample(pair.target, 0.25).points;
  for (auto _ : state) {
    autocal::lidar::IcpTarget prepared(target, /*with_normals=*/true);
    benchmark::DoNotOptimize(prepared.normals().normals.data());
  }
  state.counters["points"] = static_cast<double>(target.cols());
}
BENCHMARK(BM_TargetPreparation)->Unit(benchmark::kMillisecond);

void BM_AlignPreparedTarget(benchmark::State& state) {
  REQUIRE_PAIR(state);
  const Eigen::Matrix3Xd source = autocal::lidar::VoxelDownsample(pair.source, 0.25).points;
  const autocal::lidar::IcpTarget target(autocal::lidar::VoxelDownsample(pair.target, 0.25).points,
                                         true);
  const autocal::lidar::IcpOptions setting;
  int iterations = 0;
  for (auto _ : state) {
    const autocal::lidar::IcpResult result =
        autocal::lidar::AlignIcp(source, target, autocal::geometry::Pose3d::Identity(), setting);
    iterations = result.iterations;
  }
  state.counters["icp_iterations"] = iterations;
}
BENCHMARK(BM_AlignPreparedTarget)->Unit(benchmark::kMillisecond);

// The whole pipeline of autocal_register: downsample both, prepare the target, align.
// Argument 0: point-to-plane, 1: GICP (source normals too).
void BM_RegisterScanPair(benchmark::State& state) {
  REQUIRE_PAIR(state);
  autocal::lidar::RegistrationOptions setting;
  setting.voxel_m = 0.25;
  if (state.range(0) == 1) setting.icp.method = autocal::lidar::IcpMethod::kGeneralized;
  for (auto _ : state) {
    benchmark::DoNotOptimize(autocal::lidar::RegisterPointClouds(
        pair.source, pair.target, autocal::geometry::Pose3d::Identity(), setting));
  }
}
BENCHMARK(BM_RegisterScanPair)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

}  // namespace

// The local map of 10 sweeps taking in 30 sweeps of a 400 x 400 plane of 0.25 m voxels, each
// 1 m farther along the plane than the last (a drive over a flat ground or past a wall):
// range(0) is the axis along which the plane is constant (2: ground). Every axis should cost
// the same: the hash spreads the voxels of any plane over the table.
void BM_LocalVoxelMapSlidingPlane(benchmark::State& state) {
  constexpr int kSide = 400;
  constexpr int kSweeps = 30;
  const int fixed_axis = static_cast<int>(state.range(0));
  std::vector<Eigen::Matrix3Xd> sweeps;
  for (int k = 0; k < kSweeps; ++k) {
    Eigen::Matrix3Xd points(3, kSide * kSide);
    for (int i = 0; i < kSide; ++i) {
      for (int j = 0; j < kSide; ++j) {
        Eigen::Vector3d p = Eigen::Vector3d::Constant(-1.6);
        p((fixed_axis + 1) % 3) = 0.25 * i + 0.1 + 1.0 * k;
        p((fixed_axis + 2) % 3) = 0.25 * j + 0.1;
        points.col(i * kSide + j) = p;
      }
    }
    sweeps.push_back(std::move(points));
  }
  double mean_probe_length = 0.0;
  for (auto _ : state) {
    autocal::lidar::LocalVoxelMap map(0.25, 10);
    for (const Eigen::Matrix3Xd& sweep : sweeps) map.AddSweep(sweep);
    mean_probe_length = map.MeanProbeLength();
  }
  state.counters["mean_probe_length"] = mean_probe_length;
}
BENCHMARK(BM_LocalVoxelMapSlidingPlane)
    ->ArgName("constant_axis")
    ->Arg(0)
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond);

BENCHMARK_MAIN();
