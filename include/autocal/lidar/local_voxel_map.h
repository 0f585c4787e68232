#pragma once

// The odometry's local map (docs/lidar.md §5): the last few sweeps in W, as the centroids of
// a world-aligned voxel grid. Each voxel keeps the running sum and count of the points the
// kept sweeps put into it, so adding the newest sweep and dropping the oldest touch only
// their own points instead of re-voxelizing the whole map.

#include <Eigen/Core>
#include <cstdint>
#include <deque>
#include <vector>

namespace autocal {
namespace lidar {

class LocalVoxelMap {
 public:
  // Throws autocal::Error unless voxel_m > 0 and max_sweeps >= 1.
  LocalVoxelMap(double voxel_m, int max_sweeps);

  // Adds a sweep's points (in W); the oldest sweep leaves once more than max_sweeps are
  // kept. Throws autocal::Error on a non-finite point or one beyond ±2^20 voxels of W's origin.
  void AddSweep(const Eigen::Matrix3Xd& points_W);
  // Replaces the oldest kept sweep's points (the first sweep, once it can be deskewed).
  void ReplaceOldest(const Eigen::Matrix3Xd& points_W);

  // One centroid per occupied voxel, in voxel-slot order (deterministic for a given
  // sequence of calls).
  Eigen::Matrix3Xd Centroids() const;
  int num_sweeps() const { return static_cast<int>(sweeps_.size()); }
  // How far the hash table spreads the voxels: the mean number of entries a stored voxel sits
  // past its home entry (0 when every voxel is at its home). Finding or adding a voxel reads
  // about that many entries more than one. Walks the whole table; for tests and benchmarks.
  double MeanProbeLength() const;

 private:
  struct Voxel {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    int64_t count = 0;
  };
  // A sweep's share of one voxel.
  struct Contribution {
    int32_t slot;
    int32_t count;
    Eigen::Vector3d sum;
  };
  using SweepContributions = std::vector<Contribution>;

  // Open addressing with linear probing: the key table is kEmpty where no voxel lives.
  static constexpr uint64_t kEmpty = ~uint64_t{0};
  size_t Home(uint64_t key) const;
  void Grow();
  void Erase(uint64_t key);

  SweepContributions Contribute(const Eigen::Matrix3Xd& points_W);
  void Remove(const SweepContributions& sweep);
  int32_t SlotOf(uint64_t key);

  double voxel_m_;
  int max_sweeps_;
  std::deque<SweepContributions> sweeps_;
  std::vector<Voxel> voxels_;
  std::vector<int32_t> free_slots_;
  std::vector<uint64_t> table_keys_;
  std::vector<int32_t> table_slots_;
  // 64 - log2(table size): Home keeps the product's top bits.
  int home_shift_ = 64;
  size_t num_voxels_ = 0;
  std::vector<uint64_t> key_of_slot_;
  // Contribute's scratch: the index in its output of each slot's contribution, -1 outside it.
  std::vector<int32_t> contribution_of_slot_;
};

}  // namespace lidar
}  // namespace autocal
