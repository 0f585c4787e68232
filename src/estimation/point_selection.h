#pragma once

// Choice of a sweep's residual and map points, shared by the batch solver and the sliding
// window (docs/estimation.md, "Batch LiDAR-inertial solve"; docs/sliding_window.md).

#include <cstdint>
#include <vector>

#include "autocal/lidar/point_cloud.h"

namespace autocal {
namespace estimation {
namespace internal {

// floor(x) as an integer without a call to floor() (the portable build has no SSE4.1 rounding
// instruction): truncation, one down for negative fractions. x within the range of int64_t.
inline int64_t FloorToInt(double x) {
  const int64_t truncated = static_cast<int64_t>(x);
  return truncated - (static_cast<double>(truncated) > x);
}

// Indices of one point per occupied voxel of edge voxel_m (the first met, so a representative
// keeps its exact coordinates and time), points closer than min_range_m dropped, and those
// farther than max_range_m when it is positive. The grid spans +-2^20 voxels around the sensor
// (630 km at 0.6 m): points beyond it, or not finite, are dropped. Throws autocal::Error for a
// voxel_m that is not positive and finite or whose inverse overflows.
std::vector<int> OnePointPerVoxel(const lidar::PointCloud& cloud, double voxel_m,
                                  double min_range_m, double max_range_m = 0.0);

// Evenly spread indices so that at most max_count remain (all when max_count <= 0).
std::vector<int> Thin(const std::vector<int>& indices, int max_count);

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
