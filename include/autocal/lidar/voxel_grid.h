#pragma once

// Voxel-grid downsampling (docs/lidar.md §2.2): space is cut into cubes of edge voxel_m
// aligned with the cloud's frame, and every occupied cube is replaced by the centroid of
// its points (intensity and time are averaged the same way).

#include "autocal/lidar/point_cloud.h"

namespace autocal {
namespace lidar {

// Throws autocal::Error when voxel_m is not positive, the cloud fails CheckPointCloud, or it
// spans more than 2^21 voxels along an axis. The output is ordered by voxel index, so which
// voxels there are and their order do not depend on the input order. A voxel's points are
// summed in input order, so its centroid, mean time and mean intensity do, by rounding only:
// not at all for one or two points, and for n points by at most about 2n * 2^-53 times the
// largest magnitude among the summed values (the float intensity by one float step more).
// docs/lidar.md §2.2 gives the figures, and the cost of removing it.
PointCloud VoxelDownsample(const PointCloud& cloud, double voxel_m);

}  // namespace lidar
}  // namespace autocal
