// The batch's pass of the pairing engine (sweep_pairing.h, PairEverySweep).

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <memory>

#include "autocal/common/parallel_for.h"
#include "autocal/common/time.h"
#include "autocal/factors/point_to_plane_factor.h"
#include "estimation/firing_poses.h"
#include "estimation/sweep_pairing.h"

namespace autocal {
namespace estimation {
namespace internal {

namespace {

// Sweeps associated together per thread: their plane maps, and those of the partners they
// reach, are held at once.
constexpr int kAssociationStretchPerThread = 32;

// Plane map j from sweep j's map points deskewed into W and those of its
// map_neighbor_sweeps neighbours on each side (a denser local map, whose parts are too close
// in time to disagree much). Maps are built for the stretch of sweeps that the next points
// pair with and dropped once no later point can reach them, so that a long log never holds
// them all.
class StretchMaps {
 public:
  StretchMaps(const SweepsAtEstimate& at, const lidar::PlaneMapOptions& options, int reach,
              int num_threads)
      : at_(at),
        options_(options),
        reach_(reach),
        num_threads_(num_threads),
        points_W_(at.sweeps->size()),
        maps_(at.sweeps->size()) {}

  // Builds the missing maps of sweeps first..last (clamped to the log).
  void Cover(int first, int last) {
    const int n = at_.num_sweeps();
    const int reach = reach_;
    first = std::max(first, 0);
    last = std::min(last, n - 1);
    Build(
        std::max(0, first - reach), std::min(n - 1, last + reach),
        [&](int j) { return points_W_[static_cast<size_t>(j)].cols() == 0; },
        [&](int j) { points_W_[static_cast<size_t>(j)] = PointsInWorld(j); });
    Build(
        first, last, [&](int j) { return !maps_[static_cast<size_t>(j)]; },
        [&](int j) { maps_[static_cast<size_t>(j)] = MapOf(j); });
  }
  // Drops the maps before sweep j and the points no later map needs.
  void DropBefore(int j) {
    for (int i = 0; i < std::min(j, at_.num_sweeps()); ++i) maps_[static_cast<size_t>(i)].reset();
    for (int i = 0; i < std::min(j - reach_, at_.num_sweeps()); ++i) {
      points_W_[static_cast<size_t>(i)] = Eigen::Matrix3Xd();
    }
  }
  const lidar::PlaneMap& map(int j) const { return *maps_[static_cast<size_t>(j)]; }

 private:
  template <typename Missing, typename Make>
  void Build(int first, int last, Missing missing, Make make) const {
    std::vector<int> todo;
    for (int j = first; j <= last; ++j) {
      if (missing(j)) todo.push_back(j);
    }
    ParallelFor(0, static_cast<int64_t>(todo.size()), num_threads_,
                [&](int64_t begin, int64_t end, int) {
                  for (int64_t i = begin; i < end; ++i) make(todo[static_cast<size_t>(i)]);
                });
  }
  Eigen::Matrix3Xd PointsInWorld(int j) const {
    const size_t k = static_cast<size_t>(j);
    const SelectedSweep& sweep = (*at_.sweeps)[k];
    return SweepPointsInWorld(*at_.tables[k], (*at_.keyframes)[k], sweep, sweep.map_points, at_.g_W,
                              *at_.calibration);
  }
  std::unique_ptr<lidar::PlaneMap> MapOf(int j) const {
    const int first = std::max(0, j - reach_);
    const int last = std::min(at_.num_sweeps() - 1, j + reach_);
    Eigen::Index size = 0;
    for (int i = first; i <= last; ++i) size += points_W_[static_cast<size_t>(i)].cols();
    Eigen::Matrix3Xd local(3, size);
    Eigen::Index column = 0;
    for (int i = first; i <= last; ++i) {
      const Eigen::Matrix3Xd& part = points_W_[static_cast<size_t>(i)];
      local.middleCols(column, part.cols()) = part;
      column += part.cols();
    }
    return std::make_unique<lidar::PlaneMap>(local, options_);
  }

  const SweepsAtEstimate& at_;
  lidar::PlaneMapOptions options_;
  int reach_;  // neighbour sweeps on each side in a map
  int num_threads_;
  std::vector<Eigen::Matrix3Xd> points_W_;  // empty when not computed or dropped
  std::vector<std::unique_ptr<lidar::PlaneMap>> maps_;
};

// The residual points of sweep k paired.
std::vector<Association> PairSweep(const SweepsAtEstimate& at, const StretchMaps& maps,
                                   const PairingOptions& pairing, int k) {
  const sensors::Calibration& c = *at.calibration;
  const double offset_lin = c.time_offset_lidar_imu_s;
  const std::vector<int>& partners = pairing.partner_offsets;
  const size_t P = partners.size();
  const std::vector<int>& fallbacks = pairing.fallback_partner_offsets;
  const size_t sweep = static_cast<size_t>(k);
  const Keyframe& kf = (*at.keyframes)[sweep];
  const SelectedSweep& s = (*at.sweeps)[sweep];
  std::vector<Association> associations;
  associations.reserve(s.residual_points.size());
  size_t point_counter = 0;
  FiringPoses poses(kf.q_W_I, kf.p_W_I, kf.v_W_I, at.g_W);
  for (int i : s.residual_points) {
    const double tau = s.time(i);
    const factors::PropagatedPose<double>& pose =
        poses.At(tau, [&] { return at.tables[sweep]->At(s.t_ns + SecondsToNs(tau + offset_lin)); });
    factors::PointToSweepPlaneMeasurement m;
    m.p_L = s.point(i);
    m.motion = poses.motion();
    const Eigen::Vector3d p_W = factors::PointInWorld(pose, c.q_I_L, c.p_I_L, m.p_L);
    const size_t first = point_counter++;
    int partner = -1;
    geometry::Plane plane_W;
    for (size_t attempt = 0; attempt < P + fallbacks.size() && partner < 0; ++attempt) {
      const int j = k + (attempt < P ? partners[PartnerPosition(first, attempt, P, P)]
                                     : fallbacks[attempt - P]);
      if (j < 0 || j >= at.num_sweeps() || j == k) continue;
      if (maps.map(j).FindPlane(p_W, &plane_W) &&
          std::abs(plane_W.SignedDistance(p_W)) <= pairing.max_point_to_plane_m) {
        partner = j;
      }
    }
    if (partner < 0) continue;
    const geometry::Pose3d& T = at.T_W_L[static_cast<size_t>(partner)];
    m.plane_L.normal = T.q.conjugate() * plane_W.normal;
    m.plane_L.d = plane_W.d + plane_W.normal.dot(T.p);
    m.plane_motion = at.reference_motion[static_cast<size_t>(partner)];
    m.sigma_m = pairing.point_sigma_m;
    m.offset_linearization_s = offset_lin;
    associations.push_back({m, partner});
  }
  return associations;
}

}  // namespace

std::vector<std::vector<Association>> PairEverySweep(const SweepsAtEstimate& at,
                                                     const PairingOptions& pairing,
                                                     int map_neighbor_sweeps, int num_threads) {
  int reach = 0;
  for (const int offset : pairing.partner_offsets) reach = std::max(reach, std::abs(offset));
  for (const int offset : pairing.fallback_partner_offsets)
    reach = std::max(reach, std::abs(offset));
  const int stretch = kAssociationStretchPerThread * std::max(1, num_threads);
  StretchMaps maps(at, pairing.plane_map, map_neighbor_sweeps, num_threads);
  std::vector<std::vector<Association>> associations(at.sweeps->size());
  for (int first = 0; first < at.num_sweeps(); first += stretch) {
    const int end = std::min(at.num_sweeps(), first + stretch);
    maps.DropBefore(first - reach);
    maps.Cover(first - reach, end - 1 + reach);
    ParallelFor(first, end, num_threads, [&](int64_t begin, int64_t stop, int) {
      for (int64_t k = begin; k < stop; ++k) {
        associations[static_cast<size_t>(k)] = PairSweep(at, maps, pairing, static_cast<int>(k));
      }
    });
  }
  return associations;
}

PairingOptions CoarsePairing(PairingOptions pairing, double coarse) {
  pairing.plane_map.max_plane_thickness_m *= coarse;
  pairing.point_sigma_m *= coarse;
  pairing.max_point_to_plane_m *= coarse;
  return pairing;
}

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
