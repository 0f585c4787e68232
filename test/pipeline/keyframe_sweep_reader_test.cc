#include "pipeline/keyframe_sweep_reader.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <string>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/io/point_cloud_file.h"
#include "support/test_paths.h"

namespace autocal {
namespace pipeline {
namespace internal {
namespace {

// `count` sweeps of random points with times, sweep k's first x equal to k; the sweeps in
// `missing` are listed but have no file.
io::Dataset Sweeps(const std::string& name, int count, const std::vector<int>& missing = {}) {
  io::Dataset dataset;
  dataset.directory = test::OutputDir(name).string();
  std::filesystem::create_directories(std::filesystem::path(dataset.directory) / "lidar");
  for (int k = 0; k < count; ++k) {
    const std::string file = std::to_string(k) + ".ply";
    dataset.lidar_sweeps.push_back({int64_t{100'000'000} * k, file});
    if (std::find(missing.begin(), missing.end(), k) != missing.end()) continue;
    lidar::PointCloud cloud;
    cloud.points = 20.0 * Eigen::Matrix3Xd::Random(3, 200);
    cloud.points(0, 0) = 10.0 + k;
    cloud.time_s = 0.05 * (Eigen::VectorXd::Random(200).array() + 1.0);
    io::WritePly((std::filesystem::path(dataset.directory) / "lidar" / file).string(), cloud);
  }
  return dataset;
}

// Every second sweep of 75 (more than one stretch), read in order on two threads: each is the
// log's sweep, and each read sweep can be taken reduced, once.
TEST(KeyframeSweepReader, ReadsEveryStrideThSweepAndKeepsItReduced) {
  const io::Dataset dataset = Sweeps("keyframe_sweeps", 75);
  std::vector<double> progress;
  KeyframeSweepReader reader(dataset, 2, estimation::BatchPairingDefaults(), 2,
                             [&](double fraction) { progress.push_back(fraction); });
  ASSERT_EQ(reader.size(), 38u);
  for (size_t k = 0; k < reader.size(); ++k) {
    const lidar::LidarSweep& sweep = reader.Sweep(k);
    EXPECT_EQ(sweep.t_ns, dataset.lidar_sweeps[2 * k].t_ns);
    EXPECT_EQ(sweep.cloud.points(0, 0), 10.0 + 2.0 * static_cast<double>(k));
  }
  ASSERT_FALSE(progress.empty());
  EXPECT_GT(progress.size(), 1u);
  EXPECT_EQ(progress.back(), 1.0);
  // Read again (a second odometry pass): the same sweeps.
  EXPECT_EQ(reader.Sweep(5).t_ns, dataset.lidar_sweeps[10].t_ns);
  const estimation::SelectedSweep reduced = reader.TakeSelected(7);
  EXPECT_EQ(reduced.t_ns, dataset.lidar_sweeps[14].t_ns);
  EXPECT_FALSE(reduced.map_points.empty());
  EXPECT_THROW(reader.TakeSelected(7), Error);
  EXPECT_THROW(reader.TakeSelected(38), Error);
  EXPECT_THROW(reader.Sweep(38), Error);
  EXPECT_GT(reader.seconds_reading(), 0.0);
}

// A sweep never read cannot be taken; a missing file fails the read that reaches it, with its
// name, and the sweeps before it stay readable.
TEST(KeyframeSweepReader, NamesAMissingSweepAndTakesOnlyReadOnes) {
  const io::Dataset dataset = Sweeps("keyframe_sweeps_missing", 60, {50});
  KeyframeSweepReader reader(dataset, 1, estimation::BatchPairingDefaults(), 1);
  EXPECT_THROW(reader.TakeSelected(3), Error);  // not read yet
  EXPECT_EQ(reader.Sweep(3).t_ns, dataset.lidar_sweeps[3].t_ns);
  try {
    reader.Sweep(45);  // its stretch reaches sweep 50
    FAIL() << "sweep 50 is missing";
  } catch (const ParseError& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("50.ply"));
  }
  EXPECT_EQ(reader.Sweep(3).t_ns, dataset.lidar_sweeps[3].t_ns);
  EXPECT_EQ(reader.TakeSelected(3).t_ns, dataset.lidar_sweeps[3].t_ns);
}

// A sweep file without points (a LiDAR that saw nothing within its range) is named with what is
// wrong with it, not taken for a sweep without per-point time.
TEST(KeyframeSweepReader, AnEmptySweepIsNamedByItsFile) {
  const io::Dataset dataset = Sweeps("keyframe_sweeps_empty", 4);
  const std::string empty = dataset.SweepPath(2);
  io::WritePly(empty, lidar::PointCloud());
  KeyframeSweepReader reader(dataset, 1, estimation::BatchPairingDefaults(), 1, nullptr);
  try {
    reader.Sweep(0);
    ADD_FAILURE() << "an empty sweep was read";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr(empty + ": "));
    EXPECT_THAT(e.what(), ::testing::HasSubstr("the sweep holds no points"));
  }
}

}  // namespace
}  // namespace internal
}  // namespace pipeline
}  // namespace autocal
