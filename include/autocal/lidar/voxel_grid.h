#pragma once

// Voxel-grid downsampling (docs/lidar.md §2.2): space is cut into cubes of edge voxel_m
// aligned with the cloud's frame, and every occupied cube is replaced by the centroid of
// its points (intensity and time are averaged the same way).

#include "autocal/lidar/point_cloud.h"

namespace autocal {
namespace lidar {

// Throws autocal::Error when voxel_m is not positive, a point is not finite, or the cloud
// spans more than 2^21 voxels along an axis. The output is ordered by voxel index, so the
// result does not depend on the input order.
PointCloud VoxelDownsample(const PointCloud& cloud, double voxel_m);

}  // namespace lidar
}  // namespace autocal
