#include "estimation/point_selection.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <random>
#include <set>
#include <tuple>
#include <vector>

#include "autocal/common/error.h"

namespace autocal {
namespace estimation {
namespace internal {
namespace {

// The definition, spelled out: the first point (in cloud order) of each occupied voxel,
// points nearer than the minimum range skipped, and those beyond a positive maximum range. A
// point on a voxel face belongs to the voxel floor(x / v) takes as x * (1 / v), rounding and
// all.
std::vector<int> FirstPointPerVoxel(const lidar::PointCloud& cloud, double voxel_m,
                                    double min_range_m, double max_range_m = 0.0) {
  const double inv = 1.0 / voxel_m;
  std::set<std::tuple<int64_t, int64_t, int64_t>> seen;
  std::vector<int> out;
  for (int64_t i = 0; i < cloud.size(); ++i) {
    const Eigen::Vector3d p = cloud.points.col(i);
    if (p.norm() < min_range_m || (max_range_m > 0.0 && p.norm() > max_range_m)) continue;
    const auto voxel = std::make_tuple(static_cast<int64_t>(std::floor(p.x() * inv)),
                                       static_cast<int64_t>(std::floor(p.y() * inv)),
                                       static_cast<int64_t>(std::floor(p.z() * inv)));
    if (seen.insert(voxel).second) out.push_back(static_cast<int>(i));
  }
  return out;
}

// Clouds with many points per voxel, negative coordinates, points on voxel faces and a
// spread of sizes (the table's growth): the same indices as the definition.
TEST(OnePointPerVoxel, KeepsTheFirstPointOfEachVoxel) {
  std::mt19937 rng(5);
  for (int n : {0, 1, 7, 100, 5000, 40000}) {
    std::uniform_real_distribution<double> coordinate(-30.0, 30.0);
    std::uniform_int_distribution<int> grid(-150, 150);
    lidar::PointCloud cloud;
    cloud.points.resize(3, n);
    for (int i = 0; i < n; ++i) {
      // Every third point on the 0.2 m grid itself (a voxel's face).
      cloud.points.col(i) =
          i % 3 == 0 ? Eigen::Vector3d(0.2 * grid(rng), 0.2 * grid(rng), 0.2 * grid(rng))
                     : Eigen::Vector3d(coordinate(rng), coordinate(rng), 0.1 * coordinate(rng));
    }
    for (double voxel_m : {0.2, 0.6, 3.0}) {
      const std::vector<int> expected = FirstPointPerVoxel(cloud, voxel_m, 2.0);
      EXPECT_EQ(OnePointPerVoxel(cloud, voxel_m, 2.0), expected) << n << " points, " << voxel_m;
      // Up to 25 m: the cloud reaches 42 m.
      const std::vector<int> within = FirstPointPerVoxel(cloud, voxel_m, 2.0, 25.0);
      EXPECT_EQ(OnePointPerVoxel(cloud, voxel_m, 2.0, 25.0), within) << n << " points, " << voxel_m;
      if (n >= 5000) {
        EXPECT_LT(within.size(), expected.size());
      }
      if (n >= 5000) {
        EXPECT_LT(expected.size(), static_cast<size_t>(n));  // voxels with several points
      }
    }
  }
}

// Any finite positive voxel size is defined behaviour: the index is range-checked before the
// conversion to an integer (a 1e-300 m voxel overflowed it), points beyond the grid's +-2^20
// voxels are dropped, and a size whose inverse overflows is refused.
TEST(OnePointPerVoxel, ExtremeVoxelSizesAreDefined) {
  lidar::PointCloud cloud;
  cloud.points.resize(3, 5);
  cloud.points << 3.0, -4.0, 10.0, 50.0, 1e6,  //
      1.0, 2.0, -7.0, 0.5, 0.0,                //
      0.0, 0.3, 1.0, -2.0, 0.0;
  // Huge voxels: every point falls into one of the eight voxels around the origin.
  const std::vector<int> huge = OnePointPerVoxel(cloud, 1e308, 0.0);
  EXPECT_EQ(huge, FirstPointPerVoxel(cloud, 1e308, 0.0));
  EXPECT_LE(huge.size(), 5u);
  // Tiny voxels put every point beyond the grid: none is kept.
  for (double voxel_m : {1e-300, 1e-200, 1e-12}) {
    EXPECT_TRUE(OnePointPerVoxel(cloud, voxel_m, 0.0).empty()) << voxel_m;
  }
  // Beyond the grid at an ordinary size: the point 1000 km away is dropped, not aliased.
  EXPECT_EQ(OnePointPerVoxel(cloud, 0.6, 0.0), (std::vector<int>{0, 1, 2, 3}));
  for (double voxel_m : {0.0, -0.6, 1e-310, std::nan(""), HUGE_VAL}) {
    EXPECT_THROW(OnePointPerVoxel(cloud, voxel_m, 0.0), Error) << voxel_m;
  }
}

TEST(Thin, SpreadsAtMostTheCount) {
  std::vector<int> indices(10);
  for (int i = 0; i < 10; ++i) indices[static_cast<size_t>(i)] = 3 * i;
  EXPECT_EQ(Thin(indices, 0), indices);
  EXPECT_EQ(Thin(indices, 20), indices);
  EXPECT_EQ(Thin(indices, 5), (std::vector<int>{0, 6, 12, 18, 24}));
  EXPECT_EQ(Thin(indices, 3), (std::vector<int>{0, 9, 18}));
}

}  // namespace
}  // namespace internal
}  // namespace estimation
}  // namespace autocal
