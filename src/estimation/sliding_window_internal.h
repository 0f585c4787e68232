#pragma once

// Private state of the sliding window shared by its source files (docs/sliding_window.md).

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <vector>

#include <ceres/ceres.h>

#include "autocal/estimation/plane_map.h"
#include "autocal/estimation/sliding_window.h"
#include "autocal/factors/point_to_sweep_plane_group_factor.h"
#include "factors/point_group_storage.h"
#include "autocal/geometry/se3.h"
#include "autocal/lidar/point_cloud.h"
#include "autocal/sensors/imu_preintegration.h"
#include "estimation/point_selection.h"
#include "estimation/sliding_window_factors.h"

namespace autocal {
namespace estimation {

namespace internal {

// The residual points of one keyframe paired with planes of one partner keyframe's sweep: one
// residual block (Eq. P9) over both keyframes' q, p, v and q_I_L, p_I_L, time offset.
struct SweepPointGroup {
  int partner_id = 0;  // the partner keyframe's id
  std::unique_ptr<factors::PointToSweepPlaneGroupFactor> factor;
  // The residual point (index in its keyframe's residual_points) of each of factor's points.
  std::vector<int> point_index;
  // The block the solver sees: `factor` compressed (Eq. SW5) when it has more rows than that.
  std::unique_ptr<CompressedPointGroup> compressed;
  std::vector<double*> parameters;
  // Its linearization (Eq. SW7), made at an update's first pass and kept by later ones while
  // its points moved by at most relinearization_tolerance_m since (Eq. SW12), with what that
  // bound compares: both sweeps' LiDAR poses and velocities and the time offset then. A
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

}  // namespace internal

// The point storage of the window's groups, kept for reuse: a group of a few thousand points
// is a megabyte, which the allocator may hand back to the system when freed, so that its next
// use pays a page fault per 4 kB (in a virtual machine, about 10 microseconds each). Each
// storage is reserved for all the residual points of a keyframe, the most a group can hold,
// so that a group never grows out of it (the reservation is address space: a page is only
// mapped when first written). The pool keeps the storage of dropped groups for the next
// groups formed, preferring one already written as far as the new group needs, and per chunk
// of the association's loop the buffer in which a walk forms the terms of the points it
// pairs anew. Shared by the window's keyframes; Keep, Retire and Take are safe to use from
// the association's threads.
class SlidingWindowEstimator::TermsPool {
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
  void Retire(internal::SweepPointGroup* group) {
    group->compressed.reset();  // it refers to the factor
    Keep(factors::ReleasePoints(std::move(group->factor)).points);
  }
  // Retires the groups of `groups` paired with keyframe `partner_id`; the others keep their
  // order.
  void RetireGroupsOf(std::vector<internal::SweepPointGroup>* groups, int partner_id) {
    const auto dropped = std::stable_partition(
        groups->begin(), groups->end(),
        [partner_id](const internal::SweepPointGroup& g) { return g.partner_id != partner_id; });
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
  // The walk's buffer of chunk `chunk` of the association's loop over `chunks` chunks, kept
  // from walk to walk. Resize before the loop (not thread safe); each chunk then uses its own.
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

struct SlidingWindowEstimator::WindowKeyframe {
  int id = 0;
  SlidingWindowState state;
  // The sweep that made this keyframe (none for the initial keyframe) and its chosen points.
  std::optional<lidar::LidarSweep> sweep;
  double sweep_duration_s = 0.0;
  std::vector<int> residual_points;
  // The residual points' coordinates, times and ranges, in their order (contiguous for the
  // pairing, which visits them in turn).
  Eigen::Matrix3Xd residual_p_L;
  std::vector<double> residual_time_s;
  std::vector<double> residual_ranges_m;
  std::vector<int> map_points;
  // Preintegration from the previous keyframe (none for the oldest in the window).
  std::unique_ptr<sensors::ImuPreintegration> imu_from_previous;
  // Factors on this keyframe alone (or with calibration blocks): the initial-state prior,
  // wheel and GNSS samples of the interval that starts here.
  std::vector<internal::AttachedFactor> factors;
  // The sweep's plane map in its LiDAR frame at the reference instant (point time 0), and the
  // sweep's motion in that frame to its last point, T_L0_L(tau_max), it was deskewed with
  // (docs/sliding_window.md, "Reuse between updates", Eq. SW4).
  std::unique_ptr<PlaneMap> plane_map;
  geometry::Pose3d map_deskew_end;
  double map_max_range_m = 0.0;
  int map_generation = 0;  // counts the map's builds
  // This keyframe's residual points paired with other window sweeps: per residual point the
  // position in partner_keyframe_offsets of its partner (-1: none); the points grouped by
  // partner (a group keeps each point's terms); the range of its farthest residual point.
  std::vector<int> partner_position;
  // Per residual point its plane lookups in a row that found no plane (max_plane_misses),
  // counted since the map generation misses_map_generation.
  std::vector<uint8_t> plane_misses;
  int misses_map_generation = -1;
  // How many partner positions its points try (Eq. SW15): all when the extrinsic was still
  // converging at its first pairing, settled_partner_count when it had settled.
  size_t partner_walk = 0;
  std::vector<internal::SweepPointGroup> point_groups;
  double residual_max_range_m = 0.0;
  // The tries of the pairing ("Reuse between updates"): per partner position q the relative
  // poses T_Lj_Lk the points were tried at, with the generations of both sweeps' maps then,
  // and per residual point r and q the index in tries[q] of its last try, tried_at[r * P + q]
  // (-1: not tried since it last mattered).
  struct Try {
    geometry::Pose3d T_Lj_Lk;
    int map_generation = 0;
    int partner_map_generation = 0;
  };
  std::vector<std::vector<Try>> tries;
  std::vector<int> tried_at;
  // Per partner position q < partner_walk, whether its sweep was in the window at the last
  // pairing, and which of tries[q] some point referred to then.
  std::vector<bool> partner_present;
  std::vector<std::vector<uint8_t>> tries_in_use;
};

// A marginalized keyframe's conditional (Eq. M4) and what its kept blocks were: a block of
// a keyframe (by id, and index in StateBlocks) or a calibration block (its address in the
// estimator's calibration, keyframe_id -1).
struct SlidingWindowEstimator::SmoothingStep {
  struct BlockRef {
    int keyframe_id = -1;
    int state_block = 0;
    const double* calibration = nullptr;
  };
  int keyframe_id = 0;
  MarginalConditional conditional;
  std::vector<int> marginalized;  // index in StateBlocks of each conditional's marginalized block
  std::vector<BlockRef> kept;
};

// One window problem and the cost functions it alone uses (the problem owns nothing).
struct SlidingWindowEstimator::ProblemBuild {
  std::vector<std::unique_ptr<ceres::CostFunction>> owned;
  std::unique_ptr<ceres::Problem> problem;
  // The rows the solver evaluates at every iteration (Eq. SW11): the IMU factors, the rows
  // with a robust loss and, without linearization per pass, every row.
  std::vector<ceres::ResidualBlockId> relinearized;
};

namespace internal {

// One calibration block as the window problem holds it: a quaternion (ambient 4, tangent 3,
// RightQuaternionManifold) or a Euclidean block.
struct CalibrationBlock {
  const char* name;  // as in CalibrationCovariance::names
  double* values;
  int ambient_size;
  int tangent_size;
  bool estimated;
};

// The calibration's blocks in the order of CalibrationCovariance.
inline std::vector<CalibrationBlock> CalibrationBlocks(sensors::Calibration* c,
                                                       const SlidingWindowEstimatedBlocks& e) {
  return {{"q_I_L", c->q_I_L.coeffs().data(), 4, 3, e.extrinsic_rotation},
          {"p_I_L", c->p_I_L.data(), 3, 3, e.extrinsic_translation},
          {"time_offset_lidar_imu_s", &c->time_offset_lidar_imu_s, 1, 1, e.time_offset},
          {"wheel_radius_left_m", &c->wheel_radius_left_m, 1, 1, e.wheel_radii},
          {"wheel_radius_right_m", &c->wheel_radius_right_m, 1, 1, e.wheel_radii},
          {"track_width_m", &c->track_width_m, 1, 1, e.track_width},
          {"q_I_V", c->q_I_V.coeffs().data(), 4, 3, e.vehicle_frame},
          {"p_I_V", c->p_I_V.data(), 3, 3, e.vehicle_frame},
          {"p_I_A", c->p_I_A.data(), 3, 3, e.gnss_lever_arm}};
}

// The five state blocks of a keyframe, in the order the IMU factor and the priors take them.
inline std::vector<double*> StateBlocks(SlidingWindowState* s) {
  return {s->q_W_I.coeffs().data(), s->p_W_I.data(), s->v_W_I.data(), s->b_g.data(),
          s->b_a.data()};
}

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
