#include "estimation/batch_association.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <memory>

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

// Step 2: plane map j from sweep j's map points deskewed into W and those of its
// map_neighbor_sweeps neighbours on each side (a denser local map, whose parts are too close
// in time to disagree much). Maps are built for the stretch of sweeps that the next points
// pair with and dropped once no later point can reach them, so that a long log never holds
// them all.
class StretchMaps {
 public:
  StretchMaps(const BatchInputs& in, const PropagatedSweeps& at,
              const lidar::PlaneMapOptions& options)
      : in_(in), at_(at), options_(options), points_W_(in.sweeps.size()), maps_(in.sweeps.size()) {}

  // Builds the missing maps of sweeps first..last (clamped to the log).
  void Cover(int first, int last) {
    const int n = in_.num_sweeps();
    const int reach = in_.options.map_neighbor_sweeps;
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
    const int reach = in_.options.map_neighbor_sweeps;
    for (int i = 0; i < std::min(j, in_.num_sweeps()); ++i) maps_[static_cast<size_t>(i)].reset();
    for (int i = 0; i < std::min(j - reach, in_.num_sweeps()); ++i) {
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
    ParallelFor(0, static_cast<int64_t>(todo.size()), in_.options.num_threads,
                [&](int64_t begin, int64_t end, int) {
                  for (int64_t i = begin; i < end; ++i) make(todo[static_cast<size_t>(i)]);
                });
  }
  Eigen::Matrix3Xd PointsInWorld(int j) const {
    const size_t k = static_cast<size_t>(j);
    return internal::SweepPointsInWorld(*at_.tables[k], (*in_.keyframes)[k], in_.sweeps[k],
                                        in_.sweeps[k].map_points, in_.g_W, *in_.calibration);
  }
  std::unique_ptr<lidar::PlaneMap> MapOf(int j) const {
    const int first = std::max(0, j - in_.options.map_neighbor_sweeps);
    const int last = std::min(in_.num_sweeps() - 1, j + in_.options.map_neighbor_sweeps);
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

  const BatchInputs& in_;
  const PropagatedSweeps& at_;
  lidar::PlaneMapOptions options_;
  std::vector<Eigen::Matrix3Xd> points_W_;  // empty when not computed or dropped
  std::vector<std::unique_ptr<lidar::PlaneMap>> maps_;
};

// Step 3 for the residual points of sweep k.
std::vector<Association> AssociateSweep(const BatchInputs& in, const PropagatedSweeps& at,
                                        const StretchMaps& maps, const IterationScale& scale,
                                        int k) {
  const sensors::Calibration& c = *in.calibration;
  const double offset_lin = c.time_offset_lidar_imu_s;
  const std::vector<int>& partners = in.options.pairing.partner_offsets;
  const size_t P = partners.size();
  const size_t sweep = static_cast<size_t>(k);
  const Keyframe& kf = (*in.keyframes)[sweep];
  const SelectedSweep& s = in.sweeps[sweep];
  std::vector<Association> associations;
  size_t point_counter = 0;
  internal::FiringPoses poses(kf.q_W_I, kf.p_W_I, kf.v_W_I, in.g_W);
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
    for (size_t attempt = 0; attempt < P && partner < 0; ++attempt) {
      const int j = k + partners[internal::PartnerPosition(first, attempt, P, P)];
      if (j < 0 || j >= in.num_sweeps() || j == k) continue;
      if (maps.map(j).FindPlane(p_W, &plane_W) &&
          std::abs(plane_W.SignedDistance(p_W)) <= scale.max_point_to_plane_m) {
        partner = j;
      }
    }
    if (partner < 0) continue;
    const geometry::Pose3d& T = at.T_W_L[static_cast<size_t>(partner)];
    m.plane_L.normal = T.q.conjugate() * plane_W.normal;
    m.plane_L.d = plane_W.d + plane_W.normal.dot(T.p);
    m.plane_motion = at.reference_motion[static_cast<size_t>(partner)];
    m.sigma_m = scale.point_sigma_m;
    m.offset_linearization_s = offset_lin;
    associations.push_back({m, partner});
  }
  return associations;
}

}  // namespace

// Step 3: each point is paired with a plane of another sweep (Eq. P6), the partners tried in
// the order of pairing.partner_offsets, starting at a different one for consecutive points,
// so that every sweep is tied to sweeps before and after it. Sweeps are associated in
// stretches, each with the maps of the sweeps its partners reach.
std::vector<std::vector<Association>> AssociatePoints(const BatchInputs& in,
                                                      const PropagatedSweeps& at,
                                                      const IterationScale& scale) {
  const std::vector<int>& partners = in.options.pairing.partner_offsets;
  int reach = 0;
  for (const int offset : partners) reach = std::max(reach, std::abs(offset));
  const int stretch = kAssociationStretchPerThread * std::max(1, in.options.num_threads);
  StretchMaps maps(in, at, scale.map_options);
  std::vector<std::vector<Association>> associations(in.sweeps.size());
  for (int first = 0; first < in.num_sweeps(); first += stretch) {
    const int end = std::min(in.num_sweeps(), first + stretch);
    maps.DropBefore(first - reach);
    maps.Cover(first - reach, end - 1 + reach);
    ParallelFor(first, end, in.options.num_threads, [&](int64_t begin, int64_t stop, int) {
      for (int64_t k = begin; k < stop; ++k) {
        associations[static_cast<size_t>(k)] =
            AssociateSweep(in, at, maps, scale, static_cast<int>(k));
      }
    });
  }
  return associations;
}

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
