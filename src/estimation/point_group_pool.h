#pragma once

// The sliding window's point groups and their storage, kept for reuse: a group of a few
// thousand points is a megabyte, which the allocator may hand back to the system when freed,
// so that its next use pays a page fault per 4 kB (in a virtual machine, about 10 microseconds
// each). Each storage is reserved for all the residual points of a keyframe, the most a group
// can hold, so that a group never grows out of it (the reservation is address space: a page is
// only mapped when first written).

#include <ceres/ceres.h>

#include <algorithm>
#include <memory>
#include <mutex>
#include <optional>
#include <vector>

#include "autocal/factors/point_to_sweep_plane_group_factor.h"
#include "autocal/geometry/se3.h"
#include "estimation/sliding_window_factors.h"
#include "factors/point_group_storage.h"

namespace autocal {
namespace estimation {
namespace internal {

// The residual points of one keyframe paired with planes of one partner keyframe's sweep: one
// residual block (Eq. P9) over both keyframes' q, p, v and q_I_L, p_I_L, time offset.
struct SweepPointGroup {
  int partner_id = 0;  // the partner keyframe's id
  std::unique_ptr<factors::PointToSweepPlaneGroupFactor> factor;
  // The residual point (index in its keyframe's residual points) of each of factor's points.
  std::vector<int> point_index;
  // The block the solver sees: `factor` compressed (Eq. W3) when it has more rows than that.
  std::unique_ptr<CompressedPointGroup> compressed;
  std::vector<double*> parameters;
  // Its linearization ("Linearized once per pass"), made at an update's first pass and kept by
  // later ones while its points moved by at most relinearization_tolerance_m since (Eq. W6), with
  // what that bound compares: both sweeps' LiDAR poses and velocities and the time offset then. A
  // problem that holds `cost` must be dropped before the next BuildProblem replaces it.
  struct Linearization {
    std::unique_ptr<ceres::CostFunction> cost;
    geometry::Pose3d T_W_Lk;
    geometry::Pose3d T_W_Lj;
    Eigen::Vector3d v_W_Ik = Eigen::Vector3d::Zero();
    Eigen::Vector3d v_W_Ij = Eigen::Vector3d::Zero();
    double offset_s = 0.0;
  };
  std::optional<Linearization> linearization;

  ceres::CostFunction* solver_cost() const {
    return compressed ? static_cast<ceres::CostFunction*>(compressed.get()) : factor.get();
  }
};

// Keeps the storage of dropped groups for the next groups formed, preferring one already
// written as far as the new group needs, and per chunk of the pairing's loop the buffer in
// which a walk forms the terms of the points it pairs anew. Keep, Retire and Take are safe to
// use from the pairing's threads.
class PointGroupPool {
 public:
  using Storage = std::vector<factors::PointToSweepPlaneFactor::Terms>;
  // More than the groups of a window with the default partners: the pool frees nothing in
  // steady state.
  static constexpr size_t kMaxKept = 128;

  // Keeps `storage`, emptied, among the kMaxKept that were written farthest: as far as its
  // size or `written` terms, whichever is more.
  void Keep(Storage storage, size_t written = 0) {
    if (storage.capacity() == 0) return;
    Kept kept{std::max(written, storage.size()), std::move(storage)};
    kept.storage.clear();
    std::lock_guard<std::mutex> lock(mutex_);
    if (kept_.size() < kMaxKept) {
      kept_.push_back(std::move(kept));
      return;
    }
    auto least = std::min_element(kept_.begin(), kept_.end(), [](const Kept& a, const Kept& b) {
      return a.written < b.written;
    });
    if (kept.written > least->written) *least = std::move(kept);
  }
  // Drops `group`'s factor (and its compressed form), keeping its storage (a factor already
  // released leaves none).
  void Retire(SweepPointGroup* group) {
    group->compressed.reset();  // it refers to the factor
    Keep(factors::ReleasePoints(std::move(group->factor)).points);
  }
  // Retires the groups of `groups` paired with keyframe `partner_id`; the others keep their
  // order.
  void RetireGroupsOf(std::vector<SweepPointGroup>* groups, int partner_id) {
    const auto dropped = std::stable_partition(
        groups->begin(), groups->end(),
        [partner_id](const SweepPointGroup& g) { return g.partner_id != partner_id; });
    for (auto g = dropped; g != groups->end(); ++g) Retire(&*g);
    groups->erase(dropped, groups->end());
  }
  // Empty storage for n terms reserved for at least `reserve` (>= n): of the kept ones that
  // hold that many, one written for n terms or more (the least such), else the one written
  // farthest; a new one when none holds them.
  Storage Take(size_t n, size_t reserve) {
    reserve = std::max(n, reserve);
    Storage storage;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      // a before b: holding `reserve` first, then written for n, then the least written for
      // n, or else the farthest written.
      const auto before = [n, reserve](const Kept& a, const Kept& b) {
        const bool a_holds = a.storage.capacity() >= reserve;
        const bool b_holds = b.storage.capacity() >= reserve;
        if (a_holds != b_holds) return a_holds;
        const bool a_written = a.written >= n, b_written = b.written >= n;
        if (a_written != b_written) return a_written;
        return a_written ? a.written < b.written : a.written > b.written;
      };
      const auto best = std::min_element(kept_.begin(), kept_.end(), before);
      if (best != kept_.end() && best->storage.capacity() >= reserve) {
        storage = std::move(best->storage);
        kept_.erase(best);
      }
    }
    storage.reserve(reserve);
    return storage;
  }
  // The walk's buffer of chunk `chunk` of the pairing's loop over `chunks` chunks, kept from
  // walk to walk. Resize before the loop (not thread safe); each chunk then uses its own.
  void SetChunks(int chunks) { fresh_.resize(static_cast<size_t>(std::max(chunks, 1))); }
  Storage& Fresh(int chunk) { return fresh_.at(static_cast<size_t>(chunk)); }

 private:
  struct Kept {
    size_t written;  // terms it held when kept: at least that much of it is mapped
    Storage storage;
  };
  std::mutex mutex_;
  std::vector<Kept> kept_;
  std::vector<Storage> fresh_;
};

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
