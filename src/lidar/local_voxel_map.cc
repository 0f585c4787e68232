#include "autocal/lidar/local_voxel_map.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "autocal/common/error.h"

namespace autocal {
namespace lidar {
namespace {

// Voxel indices within ±2^20 of W's origin, packed 21 bits per axis.
constexpr int64_t kHalfRange = int64_t{1} << 20;

uint64_t PackedKey(const Eigen::Vector3d& p_W, double inv_voxel) {
  uint64_t key = 0;
  for (int axis = 0; axis < 3; ++axis) {
    const double index = std::floor(p_W(axis) * inv_voxel);
    if (!(index >= -kHalfRange && index < kHalfRange)) {
      throw Error("LocalVoxelMap: point (" + std::to_string(p_W.x()) + ", " +
                  std::to_string(p_W.y()) + ", " + std::to_string(p_W.z()) +
                  ") m is not finite or too far from the map's origin");
    }
    key = (key << 21) | static_cast<uint64_t>(static_cast<int64_t>(index) + kHalfRange);
  }
  return key;
}

}  // namespace

LocalVoxelMap::LocalVoxelMap(double voxel_m, int max_sweeps)
    : voxel_m_(voxel_m), max_sweeps_(max_sweeps) {
  if (!(voxel_m > 0.0) || !std::isfinite(1.0 / voxel_m) || max_sweeps < 1) {
    throw Error("LocalVoxelMap: voxel_m must be positive and max_sweeps at least 1");
  }
}

size_t LocalVoxelMap::Home(uint64_t key) const {
  // Multiplicative (Fibonacci) hashing keeps the top log2(table size) bits of key * 2^64/phi,
  // which depend on every bit of the key. Once alone, it maps the lattice of a plane of
  // voxels onto a lattice of homes that may crowd (a wall of constant x: 5 entries past home
  // per voxel); the high half folded into the low one and a second multiplication spread
  // every plane as random homes would (0.2 at the table's load). The low bits of one product
  // never depend on the key's high bits, where x is packed: a ground plane of 160000 voxels
  // shared 400 homes with them.
  constexpr uint64_t kGoldenRatio64 = 0x9E3779B97F4A7C15ull;  // 2^64 / phi, odd
  uint64_t hash = key * kGoldenRatio64;
  hash ^= hash >> 32;
  return static_cast<size_t>((hash * kGoldenRatio64) >> home_shift_);
}

void LocalVoxelMap::Grow() {
  std::vector<uint64_t> keys = std::move(table_keys_);
  std::vector<int32_t> slots = std::move(table_slots_);
  table_keys_.assign(std::max<size_t>(1024, 2 * keys.size()), kEmpty);
  table_slots_.assign(table_keys_.size(), -1);
  int table_bits = 0;
  while ((size_t{1} << table_bits) < table_keys_.size()) ++table_bits;
  home_shift_ = 64 - table_bits;
  for (size_t i = 0; i < keys.size(); ++i) {
    if (keys[i] == kEmpty) continue;
    size_t at = Home(keys[i]);
    while (table_keys_[at] != kEmpty) at = (at + 1) & (table_keys_.size() - 1);
    table_keys_[at] = keys[i];
    table_slots_[at] = slots[i];
  }
}

int32_t LocalVoxelMap::SlotOf(uint64_t key) {
  if (2 * (num_voxels_ + 1) > table_keys_.size()) Grow();
  const size_t mask = table_keys_.size() - 1;
  size_t at = Home(key);
  for (; table_keys_[at] != kEmpty; at = (at + 1) & mask) {
    if (table_keys_[at] == key) return table_slots_[at];
  }
  int32_t slot;
  if (free_slots_.empty()) {
    slot = static_cast<int32_t>(voxels_.size());
    voxels_.emplace_back();
    key_of_slot_.push_back(key);
  } else {
    slot = free_slots_.back();
    free_slots_.pop_back();
    key_of_slot_[static_cast<size_t>(slot)] = key;
  }
  table_keys_[at] = key;
  table_slots_[at] = slot;
  ++num_voxels_;
  return slot;
}

// Backward-shift deletion: the entries after the hole that could live in it move back, so
// lookups never need tombstones.
void LocalVoxelMap::Erase(uint64_t key) {
  const size_t mask = table_keys_.size() - 1;
  size_t hole = Home(key);
  while (table_keys_[hole] != key) hole = (hole + 1) & mask;
  for (size_t next = (hole + 1) & mask; table_keys_[next] != kEmpty; next = (next + 1) & mask) {
    const size_t home = Home(table_keys_[next]);
    // The entry at `next` may fill the hole when its home is not in (hole, next], cyclically.
    const bool home_after_hole = ((next - home) & mask) < ((next - hole) & mask);
    if (home_after_hole) continue;
    table_keys_[hole] = table_keys_[next];
    table_slots_[hole] = table_slots_[next];
    hole = next;
  }
  table_keys_[hole] = kEmpty;
  table_slots_[hole] = -1;
  --num_voxels_;
}

// Groups the points by voxel (a sweep's points in one voxel are summed in input order) and
// adds each group to its voxel, in slot order.
LocalVoxelMap::SweepContributions LocalVoxelMap::Contribute(const Eigen::Matrix3Xd& points_W) {
  // Every key first: a bad point throws before the map changes.
  const double inv_voxel = 1.0 / voxel_m_;
  std::vector<uint64_t> keys(static_cast<size_t>(points_W.cols()));
  for (Eigen::Index i = 0; i < points_W.cols(); ++i) {
    keys[static_cast<size_t>(i)] = PackedKey(points_W.col(i), inv_voxel);
  }
  SweepContributions out;
  for (size_t i = 0; i < keys.size(); ++i) {
    const int32_t slot = SlotOf(keys[i]);
    if (static_cast<size_t>(slot) >= contribution_of_slot_.size()) {
      contribution_of_slot_.resize(voxels_.size(), -1);
    }
    int32_t& c = contribution_of_slot_[static_cast<size_t>(slot)];
    if (c < 0) {
      c = static_cast<int32_t>(out.size());
      out.push_back(Contribution{slot, 0, Eigen::Vector3d::Zero()});
    }
    out[static_cast<size_t>(c)].sum += points_W.col(static_cast<Eigen::Index>(i));
    ++out[static_cast<size_t>(c)].count;
  }
  for (const Contribution& c : out) contribution_of_slot_[static_cast<size_t>(c.slot)] = -1;
  std::sort(out.begin(), out.end(),
            [](const Contribution& a, const Contribution& b) { return a.slot < b.slot; });
  for (const Contribution& c : out) {
    Voxel& voxel = voxels_[static_cast<size_t>(c.slot)];
    voxel.sum += c.sum;
    voxel.count += c.count;
  }
  return out;
}

void LocalVoxelMap::Remove(const SweepContributions& sweep) {
  for (const Contribution& c : sweep) {
    Voxel& voxel = voxels_[static_cast<size_t>(c.slot)];
    voxel.count -= c.count;
    voxel.sum -= c.sum;
    if (voxel.count == 0) {
      voxel.sum.setZero();  // no rounding residue carries over to the slot's next voxel
      Erase(key_of_slot_[static_cast<size_t>(c.slot)]);
      free_slots_.push_back(c.slot);
    }
  }
}

void LocalVoxelMap::AddSweep(const Eigen::Matrix3Xd& points_W) {
  sweeps_.push_back(Contribute(points_W));
  while (static_cast<int>(sweeps_.size()) > max_sweeps_) {
    Remove(sweeps_.front());
    sweeps_.pop_front();
  }
}

void LocalVoxelMap::ReplaceOldest(const Eigen::Matrix3Xd& points_W) {
  if (sweeps_.empty()) throw Error("LocalVoxelMap::ReplaceOldest: the map holds no sweep");
  Remove(sweeps_.front());
  sweeps_.front() = Contribute(points_W);
}

double LocalVoxelMap::MeanProbeLength() const {
  if (num_voxels_ == 0) return 0.0;
  const size_t mask = table_keys_.size() - 1;
  size_t steps = 0;
  for (size_t at = 0; at < table_keys_.size(); ++at) {
    if (table_keys_[at] != kEmpty) steps += (at - Home(table_keys_[at])) & mask;
  }
  return static_cast<double>(steps) / static_cast<double>(num_voxels_);
}

Eigen::Matrix3Xd LocalVoxelMap::Centroids() const {
  Eigen::Matrix3Xd out(3, static_cast<Eigen::Index>(num_voxels_));
  Eigen::Index column = 0;
  for (const Voxel& voxel : voxels_) {
    if (voxel.count == 0) continue;
    out.col(column++) = voxel.sum / static_cast<double>(voxel.count);
  }
  return out;
}

}  // namespace lidar
}  // namespace autocal
