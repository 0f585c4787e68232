#include "pipeline/sweep_reader.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "autocal/common/error.h"
#include "autocal/io/point_cloud_file.h"
#include "support/test_paths.h"

namespace autocal {
namespace pipeline {
namespace internal {
namespace {

// Five sweeps of a few points each, sweep k's first x equal to k; sweep 3 listed but missing.
io::Dataset FiveSweeps() {
  io::Dataset dataset;
  dataset.directory = test::OutputDir("sweeps").string();
  std::filesystem::create_directories(std::filesystem::path(dataset.directory) / "lidar");
  for (int k = 0; k < 5; ++k) {
    const std::string file = std::to_string(k) + ".ply";
    dataset.lidar_sweeps.push_back({int64_t{100'000'000} * k, file});
    if (k == 3) continue;
    lidar::PointCloud cloud;
    cloud.points = Eigen::Matrix3Xd::Random(3, 10 + k);
    cloud.points(0, 0) = k;
    io::WritePly((std::filesystem::path(dataset.directory) / "lidar" / file).string(), cloud);
  }
  return dataset;
}

// In order, with and without the read-ahead: each Take returns its own sweep, and the missing
// one throws when taken (not when read ahead); after it the stream goes on.
TEST(SweepReader, TakesEachSweepAndFailsOnlyAtTheMissingOne) {
  const io::Dataset dataset = FiveSweeps();
  for (const bool read_ahead : {false, true}) {
    SweepReader reader(dataset, read_ahead);
    for (size_t k = 0; k < 5; ++k) {
      if (k == 3) {
        try {
          reader.Take(k);
          FAIL() << "sweep 3 is missing";
        } catch (const ParseError& e) {
          EXPECT_THAT(e.what(), ::testing::HasSubstr("3.ply"));
        }
        continue;
      }
      const lidar::LidarSweep sweep = reader.Take(k);
      EXPECT_EQ(sweep.t_ns, dataset.lidar_sweeps[k].t_ns) << read_ahead;
      ASSERT_EQ(sweep.cloud.size(), static_cast<int64_t>(10 + k));
      EXPECT_EQ(sweep.cloud.points(0, 0), static_cast<double>(k));
    }
  }
}

// Out of order (a sweep skipped, one taken twice): each Take still returns the sweep asked for.
TEST(SweepReader, TakesAnySweepAskedFor) {
  const io::Dataset dataset = FiveSweeps();
  SweepReader reader(dataset, true);
  EXPECT_EQ(reader.Take(0).cloud.points(0, 0), 0.0);
  EXPECT_EQ(reader.Take(2).cloud.points(0, 0), 2.0);  // 1 was read ahead, not taken
  EXPECT_EQ(reader.Take(2).cloud.points(0, 0), 2.0);
  EXPECT_EQ(reader.Take(4).cloud.points(0, 0), 4.0);
  EXPECT_EQ(reader.Take(1).cloud.points(0, 0), 1.0);
}

}  // namespace
}  // namespace internal
}  // namespace pipeline
}  // namespace autocal
