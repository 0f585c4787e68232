#include "estimation/point_selection.h"

#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "autocal/common/error.h"

namespace autocal {
namespace estimation {
namespace internal {

std::vector<int> OnePointPerVoxel(const lidar::PointCloud& cloud, double voxel_m,
                                  double min_range_m, double max_range_m) {
  const double max_range2_m2 =
      max_range_m > 0.0 ? max_range_m * max_range_m : std::numeric_limits<double>::infinity();
  // 21 bits per axis: +-2^20 voxels around the sensor, far beyond any LiDAR's range. The keys
  // use 63 bits, so ~0 marks an empty slot.
  constexpr int64_t kHalfRange = int64_t{1} << 20;
  constexpr uint64_t kEmpty = ~uint64_t{0};
  const double inv = 1.0 / voxel_m;
  if (!(voxel_m > 0.0) || !std::isfinite(voxel_m) || !std::isfinite(inv)) {
    throw Error(
        "OnePointPerVoxel: the voxel size must be positive, finite and not subnormal, "
        "got " +
        std::to_string(voxel_m) + " m");
  }
  // The voxel index of a coordinate, checked against the grid before any conversion to an
  // integer (a 1e-300 m voxel would overflow it); false beyond the grid or for NaN.
  const auto cell = [inv](double x, uint64_t* index) {
    const double v = x * inv;
    if (!(v > -static_cast<double>(kHalfRange) && v < static_cast<double>(kHalfRange))) {
      return false;
    }
    *index = static_cast<uint64_t>(FloorToInt(v) + kHalfRange) & 0x1FFFFF;
    return true;
  };
  // The occupied voxels in an open-addressing table at most half full (linear probing,
  // Fibonacci hashing): a sweep's tens of thousands of points without a node allocation each.
  int bits = 4;
  while ((int64_t{1} << bits) < 2 * cloud.size()) ++bits;
  const uint64_t mask = (uint64_t{1} << bits) - 1;
  std::vector<uint64_t> table(static_cast<size_t>(mask + 1), kEmpty);
  std::vector<int> out;
  for (int64_t i = 0; i < cloud.size(); ++i) {
    const Eigen::Vector3d p = cloud.points.col(i);
    const double range2_m2 = p.squaredNorm();
    if (range2_m2 < min_range_m * min_range_m || range2_m2 > max_range2_m2) continue;
    uint64_t ix = 0, iy = 0, iz = 0;
    if (!cell(p.x(), &ix) || !cell(p.y(), &iy) || !cell(p.z(), &iz)) continue;
    const uint64_t key = (ix << 42) | (iy << 21) | iz;
    uint64_t slot = (key * 0x9E3779B97F4A7C15ull) >> (64 - bits);
    while (table[slot] != kEmpty && table[slot] != key) slot = (slot + 1) & mask;
    if (table[slot] == kEmpty) {
      table[slot] = key;
      out.push_back(static_cast<int>(i));
    }
  }
  return out;
}

std::vector<int> Thin(const std::vector<int>& indices, int max_count) {
  if (max_count <= 0 || static_cast<int>(indices.size()) <= max_count) return indices;
  std::vector<int> out;
  out.reserve(static_cast<size_t>(max_count));
  const double stride = static_cast<double>(indices.size()) / max_count;
  for (int i = 0; i < max_count; ++i) out.push_back(indices[static_cast<size_t>(i * stride)]);
  return out;
}

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
