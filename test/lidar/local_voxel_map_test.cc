#include "autocal/lidar/local_voxel_map.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <deque>
#include <limits>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "autocal/common/error.h"

namespace autocal {
namespace lidar {
namespace {

using VoxelIndex = std::array<int64_t, 3>;

// The centroids of the given sweeps' points per world-aligned voxel, sorted, by brute force.
std::vector<Eigen::Vector3d> ReferenceCentroids(const std::deque<Eigen::Matrix3Xd>& sweeps,
                                                double voxel_m) {
  std::map<VoxelIndex, std::pair<Eigen::Vector3d, int>> voxels;
  for (const Eigen::Matrix3Xd& sweep : sweeps) {
    for (Eigen::Index i = 0; i < sweep.cols(); ++i) {
      const VoxelIndex index{static_cast<int64_t>(std::floor(sweep(0, i) / voxel_m)),
                             static_cast<int64_t>(std::floor(sweep(1, i) / voxel_m)),
                             static_cast<int64_t>(std::floor(sweep(2, i) / voxel_m))};
      auto& [sum, count] = voxels.try_emplace(index, Eigen::Vector3d::Zero(), 0).first->second;
      sum += sweep.col(i);
      ++count;
    }
  }
  std::vector<Eigen::Vector3d> out;
  for (const auto& [index, sum_count] : voxels) {
    out.push_back(sum_count.first / sum_count.second);
  }
  return out;
}

std::vector<Eigen::Vector3d> Sorted(const Eigen::Matrix3Xd& points) {
  std::vector<Eigen::Vector3d> out;
  for (Eigen::Index i = 0; i < points.cols(); ++i) out.push_back(points.col(i));
  std::sort(out.begin(), out.end(), [](const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    return std::lexicographical_compare(a.data(), a.data() + 3, b.data(), b.data() + 3);
  });
  return out;
}

void ExpectSameCentroids(const Eigen::Matrix3Xd& map, const std::deque<Eigen::Matrix3Xd>& sweeps,
                         double voxel_m) {
  std::vector<Eigen::Vector3d> reference = ReferenceCentroids(sweeps, voxel_m);
  std::sort(reference.begin(), reference.end(),
            [](const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
              return std::lexicographical_compare(a.data(), a.data() + 3, b.data(), b.data() + 3);
            });
  const std::vector<Eigen::Vector3d> got = Sorted(map);
  ASSERT_EQ(got.size(), reference.size());
  for (size_t i = 0; i < got.size(); ++i) {
    EXPECT_LT((got[i] - reference[i]).norm(), 1e-9) << "centroid " << i;
  }
}

// A sweep of points on a few planes around a moving sensor, so that consecutive sweeps share
// most voxels and old ones leave some voxels empty.
Eigen::Matrix3Xd RandomSweep(std::mt19937* rng, double x_offset_m) {
  std::uniform_real_distribution<double> u(-10.0, 10.0);
  Eigen::Matrix3Xd points(3, 3000);
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    const int plane = static_cast<int>(i % 3);
    points.col(i) = Eigen::Vector3d(x_offset_m + u(*rng), u(*rng), u(*rng));
    points(plane, i) = plane == 0 ? x_offset_m + 12.0 : (plane == 1 ? 8.0 : -1.5);
  }
  return points;
}

TEST(LocalVoxelMap, CentroidsAreThoseOfTheLastSweepsPoints) {
  const double voxel_m = 0.5;
  const int max_sweeps = 4;
  LocalVoxelMap map(voxel_m, max_sweeps);
  std::deque<Eigen::Matrix3Xd> kept;
  std::mt19937 rng(7);
  // 30 sweeps moving 1 m each: the table grows, voxels empty and their slots are reused.
  for (int k = 0; k < 30; ++k) {
    kept.push_back(RandomSweep(&rng, 1.0 * k));
    if (static_cast<int>(kept.size()) > max_sweeps) kept.pop_front();
    map.AddSweep(kept.back());
    ASSERT_EQ(map.num_sweeps(), static_cast<int>(kept.size()));
    ExpectSameCentroids(map.Centroids(), kept, voxel_m);
  }
  kept.front() = RandomSweep(&rng, -3.0);
  map.ReplaceOldest(kept.front());
  ExpectSameCentroids(map.Centroids(), kept, voxel_m);
}

TEST(LocalVoxelMap, GridIsAlignedWithTheWorldNotTheCloud) {
  LocalVoxelMap map(1.0, 2);
  Eigen::Matrix3Xd points(3, 2);
  points << 0.9, 1.1,  //
      0.2, 0.2,        //
      -0.5, -0.5;
  map.AddSweep(points);
  // 0.9 and 1.1 straddle the voxel boundary at x = 1: two voxels, whatever the cloud's corner.
  EXPECT_EQ(map.Centroids().cols(), 2);
}

// One voxel per point on a 400 x 400 grid of 0.25 m voxels in the plane where `fixed_axis` is
// constant.
Eigen::Matrix3Xd AxisPlane(int fixed_axis) {
  constexpr int kSide = 400;
  Eigen::Matrix3Xd points(3, kSide * kSide);
  for (int i = 0; i < kSide; ++i) {
    for (int j = 0; j < kSide; ++j) {
      Eigen::Vector3d p = Eigen::Vector3d::Constant(-1.6);
      p((fixed_axis + 1) % 3) = 0.25 * i + 0.1;
      p((fixed_axis + 2) % 3) = 0.25 * j + 0.1;
      points.col(i * kSide + j) = p;
    }
  }
  return points;
}

// Every axis-aligned plane of voxels spreads over the table alike. The home entry used to keep
// bits of the key's product that never depend on the x index: a voxel sat 199.5 entries past
// its home on average in a ground plane (z constant), 394.6 in a wall of constant y and 1.06
// in one of constant x. The top bits of one product alone gave 0.01, 0.003 and 5.2.
TEST(LocalVoxelMap, PlanesAlongEveryAxisSpreadOverTheTable) {
  const char* names[3] = {"x", "y", "z"};
  for (int fixed_axis = 0; fixed_axis < 3; ++fixed_axis) {
    LocalVoxelMap map(0.25, 10);
    map.AddSweep(AxisPlane(fixed_axis));
    ASSERT_EQ(map.Centroids().cols(), 400 * 400);
    // Linear probing at a load of 160000 / 2^19 = 0.31 with random homes: about 0.2.
    RecordProperty(std::string("mean_probe_length_constant_") + names[fixed_axis],
                   std::to_string(map.MeanProbeLength()));
    EXPECT_LT(map.MeanProbeLength(), 0.5) << names[fixed_axis] << " constant";
  }
  LocalVoxelMap empty(0.25, 10);
  EXPECT_EQ(empty.MeanProbeLength(), 0.0);
}

TEST(LocalVoxelMap, RefusesBadSettingsAndPoints) {
  EXPECT_THROW(LocalVoxelMap(0.0, 3), Error);
  EXPECT_THROW(LocalVoxelMap(0.5, 0), Error);
  LocalVoxelMap map(0.5, 3);
  Eigen::Matrix3Xd bad(3, 1);
  bad << std::numeric_limits<double>::quiet_NaN(), 0.0, 0.0;
  EXPECT_THROW(map.AddSweep(bad), Error);
  bad << 1e9, 0.0, 0.0;  // beyond 2^20 voxels of the origin
  EXPECT_THROW(map.AddSweep(bad), Error);
  EXPECT_THROW(map.ReplaceOldest(Eigen::Matrix3Xd(3, 0)), Error);
  // A refused sweep leaves the map as it was.
  Eigen::Matrix3Xd good(3, 2);
  good << 0.1, 0.2, 0.1, 0.1, 0.1, 0.1;
  map.AddSweep(good);
  Eigen::Matrix3Xd half_bad(3, 2);
  half_bad << 5.0, 1e9, 0.0, 0.0, 0.0, 0.0;
  EXPECT_THROW(map.AddSweep(half_bad), Error);
  EXPECT_EQ(map.num_sweeps(), 1);
  ASSERT_EQ(map.Centroids().cols(), 1);
  EXPECT_NEAR(map.Centroids()(0, 0), 0.15, 1e-12);
}

}  // namespace
}  // namespace lidar
}  // namespace autocal
