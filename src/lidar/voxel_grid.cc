#include "autocal/lidar/voxel_grid.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include "autocal/common/error.h"

namespace autocal {
namespace lidar {
namespace {

// Voxel indices relative to the cloud's minimum corner are packed into one 63-bit key.
constexpr int64_t kMaxVoxelsPerAxis = int64_t{1} << 21;

}  // namespace

PointCloud VoxelDownsample(const PointCloud& cloud, double voxel_m) {
  // A subnormal size has an infinite inverse: 0 * inf would make a NaN voxel index.
  if (!(voxel_m > 0.0) || !std::isfinite(voxel_m) || !std::isfinite(1.0 / voxel_m)) {
    throw Error("VoxelDownsample: voxel size must be positive, finite and not subnormal, got " +
                std::to_string(voxel_m));
  }
  CheckPointCloud(cloud, "VoxelDownsample");
  const int64_t n = cloud.size();
  if (n == 0) return PointCloud();

  const Eigen::Vector3d min_corner = cloud.points.rowwise().minCoeff();
  const Eigen::Vector3d extent = cloud.points.rowwise().maxCoeff() - min_corner;
  // Checked before any conversion to an integer; an extent that overflows (points near
  // +-1e308) is infinite and fails too.
  if (!((extent / voxel_m).maxCoeff() < static_cast<double>(kMaxVoxelsPerAxis - 1))) {
    throw Error("VoxelDownsample: the cloud spans too many voxels (extent " +
                std::to_string(extent.maxCoeff()) + " m at voxel size " + std::to_string(voxel_m) +
                " m)");
  }

  // Bits per axis actually needed for this cloud, x most significant, so that sorting the
  // packed keys groups each voxel's points and orders voxels by (x, y, z) index.
  const double inv_voxel = 1.0 / voxel_m;
  int bits[3];
  for (int axis = 0; axis < 3; ++axis) {
    const uint64_t cells = static_cast<uint64_t>(extent(axis) * inv_voxel) + 1;
    bits[axis] = 1;
    while ((uint64_t{1} << bits[axis]) < cells) ++bits[axis];
  }
  const int key_bits = bits[0] + bits[1] + bits[2];
  std::vector<uint64_t> keys(static_cast<size_t>(n));
  std::vector<uint32_t> order(static_cast<size_t>(n));
  for (int64_t i = 0; i < n; ++i) {
    const Eigen::Vector3d v = (cloud.points.col(i) - min_corner) * inv_voxel;
    const uint64_t ix = static_cast<uint64_t>(v.x());
    const uint64_t iy = static_cast<uint64_t>(v.y());
    const uint64_t iz = static_cast<uint64_t>(v.z());
    keys[i] = (ix << (bits[1] + bits[2])) | (iy << bits[2]) | iz;
    order[i] = static_cast<uint32_t>(i);
  }
  // LSD radix sort of (key, index) on 11-bit digits: linear time and stable, so points keep
  // their input order within a voxel (the centroid sums are then reproducible).
  constexpr int kDigitBits = 11;
  constexpr size_t kBuckets = size_t{1} << kDigitBits;
  std::vector<uint64_t> keys_tmp(keys.size());
  std::vector<uint32_t> order_tmp(order.size());
  std::vector<size_t> offsets(kBuckets);
  for (int shift = 0; shift < key_bits; shift += kDigitBits) {
    std::fill(offsets.begin(), offsets.end(), 0);
    for (uint64_t key : keys) ++offsets[(key >> shift) & (kBuckets - 1)];
    size_t sum = 0;
    for (size_t& offset : offsets) {
      const size_t count = offset;
      offset = sum;
      sum += count;
    }
    for (size_t i = 0; i < keys.size(); ++i) {
      const size_t slot = offsets[(keys[i] >> shift) & (kBuckets - 1)]++;
      keys_tmp[slot] = keys[i];
      order_tmp[slot] = order[i];
    }
    keys.swap(keys_tmp);
    order.swap(order_tmp);
  }

  int64_t num_voxels = 1;
  for (size_t i = 1; i < keys.size(); ++i) num_voxels += keys[i] != keys[i - 1];

  const bool has_intensity = cloud.has_intensity();
  const bool has_time = cloud.has_time();
  PointCloud out;
  out.points.resize(3, num_voxels);
  if (has_intensity) out.intensity.resize(num_voxels);
  if (has_time) out.time_s.resize(num_voxels);

  int64_t voxel = 0;
  size_t begin = 0;
  while (begin < keys.size()) {
    size_t end = begin;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    double intensity_sum = 0.0;
    double time_sum = 0.0;
    while (end < keys.size() && keys[end] == keys[begin]) {
      const uint32_t index = order[end];
      sum += cloud.points.col(index);
      if (has_intensity) intensity_sum += cloud.intensity(index);
      if (has_time) time_sum += cloud.time_s(index);
      ++end;
    }
    const double inv_count = 1.0 / static_cast<double>(end - begin);
    out.points.col(voxel) = sum * inv_count;
    if (has_intensity) out.intensity(voxel) = static_cast<float>(intensity_sum * inv_count);
    if (has_time) out.time_s(voxel) = time_sum * inv_count;
    ++voxel;
    begin = end;
  }
  return out;
}

}  // namespace lidar
}  // namespace autocal
