// LiDAR module speed on the real scan pair (../shared/data/lidar_scan_pair, or
// $AUTOCAL_SHARED_DIR/data/lidar_scan_pair): voxel downsampling, k-d tree build, target
// normals, and full point-to-plane registration at 0.25 m voxels. Single-threaded.

#include <benchmark/benchmark.h>

#include <cstdlib>
#include <filesystem>
#include <string>

#include "autocal/io/point_cloud_file.h"
#include "autocal/lidar/icp.h"
#include "autocal/lidar/kd_tree.h"
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
  const autocal::lidar::IcpSetting setting;
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
void BM_RegisterScanPair(benchmark::State& state) {
  REQUIRE_PAIR(state);
  autocal::lidar::RegistrationSetting setting;
  setting.voxel_m = 0.25;
  for (auto _ : state) {
    benchmark::DoNotOptimize(autocal::lidar::RegisterPointClouds(
        pair.source, pair.target, autocal::geometry::Pose3d::Identity(), setting));
  }
}
BENCHMARK(BM_RegisterScanPair)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
