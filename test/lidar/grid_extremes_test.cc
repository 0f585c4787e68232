// The voxel grid and the neighbour grid at extreme sizes and coordinates: every finite input
// is defined behaviour (a result or an autocal::Error), never an overflowing float-to-integer
// conversion or an endless loop.

#include <gtest/gtest.h>

#include <Eigen/Core>

#include "autocal/common/error.h"
#include "autocal/lidar/neighbor_grid.h"
#include "autocal/lidar/voxel_grid.h"

namespace autocal {
namespace lidar {
namespace {

PointCloud Cloud(const Eigen::Matrix3Xd& points) {
  PointCloud cloud;
  cloud.points = points;
  return cloud;
}

TEST(VoxelDownsampleExtremes, TinyHugeAndSubnormalSizes) {
  Eigen::Matrix3Xd one(3, 1);
  one << 1.0, 2.0, 3.0;
  // One point: any normal size keeps it (its extent is zero).
  for (double voxel_m : {1e-300, 1e-12, 0.5, 1e308}) {
    EXPECT_EQ(VoxelDownsample(Cloud(one), voxel_m).size(), 1) << voxel_m;
  }
  // A subnormal size has an infinite inverse: 0 * inf made a NaN index.
  EXPECT_THROW(VoxelDownsample(Cloud(one), 1e-310), Error);
  Eigen::Matrix3Xd two(3, 2);
  two << 0.0, 1.0, 0.0, 0.0, 0.0, 0.0;
  EXPECT_THROW(VoxelDownsample(Cloud(two), 1e-300), Error);  // too many voxels
  EXPECT_EQ(VoxelDownsample(Cloud(two), 1e308).size(), 1);
  // Finite points whose extent overflows a double.
  two << -1.5e308, 1.5e308, 0.0, 0.0, 0.0, 0.0;
  EXPECT_THROW(VoxelDownsample(Cloud(two), 1.0), Error);
}

TEST(NeighborGridExtremes, TinyRadiusAndOverflowingExtent) {
  Eigen::Matrix3Xd one(3, 1);
  one << 1.0, 2.0, 3.0;
  EXPECT_THROW(NeighborGrid(one, 1e-310), Error);
  const NeighborGrid tiny(one, 1e-300);
  Neighbor found[1];
  EXPECT_EQ(tiny.Knn(Eigen::Vector3d(1.0, 2.0, 3.0), 1, found), 1);
  EXPECT_EQ(tiny.Knn(Eigen::Vector3d(1.0, 2.0, 3.5), 1, found), 0);
  Eigen::Matrix3Xd far(3, 2);
  far << -1.5e308, 1.5e308, 0.0, 0.0, 0.0, 0.0;
  EXPECT_THROW(NeighborGrid(far, 1.0), Error);
  // Wide but finite: the edge grows until the columns fit.
  far << -1e300, 1e300, 0.0, 0.0, 0.0, 0.0;
  const NeighborGrid wide(far, 1.0);
  EXPECT_EQ(wide.Knn(Eigen::Vector3d(1e300, 0.0, 0.0), 1, found), 1);
}

}  // namespace
}  // namespace lidar
}  // namespace autocal
