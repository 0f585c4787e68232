#include "estimation/sweep_pairing.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <string>
#include <utility>

#include "autocal/common/error.h"
#include "autocal/common/parallel_for.h"
#include "autocal/common/time.h"
#include "autocal/common/units.h"
#include "autocal/factors/point_to_plane_factor.h"
#include "autocal/geometry/so3.h"
#include "estimation/firing_poses.h"
#include "estimation/keyframe_walk.h"
#include "estimation/point_selection.h"

namespace autocal {
namespace estimation {
namespace internal {

SweepSelection SelectSweepPoints(const lidar::PointCloud& cloud, const PairingOptions& setting) {
  SweepSelection selection;
  selection.residual_points =
      Thin(OnePointPerVoxel(cloud, setting.residual_voxel_m, setting.min_range_m,
                            setting.residual_max_range_m),
           setting.max_residuals_per_sweep);
  selection.map_points = OnePointPerVoxel(cloud, setting.map_voxel_m, setting.min_range_m);
  return selection;
}

geometry::Pose3d SweepLidarPose(const Keyframe& kf, const factors::PointMotion& m,
                                const Eigen::Vector3d& g_W, const Eigen::Quaterniond& q_I_L,
                                const Eigen::Vector3d& p_I_L) {
  const factors::PropagatedPose<double> pose =
      factors::PropagateKeyframe(kf.q_W_I, kf.p_W_I, kf.v_W_I, 0.0, m, g_W);
  const Eigen::Quaterniond q_W_I(pose.R_W_I);
  return geometry::Pose3d(q_W_I * q_I_L, q_W_I * p_I_L + pose.p_W_I);
}

namespace {

// SweepPointsInWorld on a sweep stamped t_ns whose point i in L is point(i), fired time_s(i)
// after t_ns.
template <typename PointAt, typename TimeAt>
Eigen::Matrix3Xd PointsInWorld(const ImuMotionTable& table, const Keyframe& kf, int64_t t_ns,
                               const std::vector<int>& indices, const Eigen::Vector3d& g_W,
                               const sensors::Calibration& c, PointAt point, TimeAt time_s) {
  Eigen::Matrix3Xd points_W(3, static_cast<Eigen::Index>(indices.size()));
  Eigen::Index column = 0;
  FiringPoses poses(kf.q_W_I, kf.p_W_I, kf.v_W_I, g_W);
  for (int i : indices) {
    const double tau = time_s(i);
    const factors::PropagatedPose<double>& pose = poses.At(
        tau, [&] { return table.At(t_ns + SecondsToNs(tau + c.time_offset_lidar_imu_s)); });
    points_W.col(column++) = factors::PointInWorld(pose, c.q_I_L, c.p_I_L, point(i));
  }
  return points_W;
}

}  // namespace

Eigen::Matrix3Xd SweepPointsInWorld(const ImuMotionTable& table, const Keyframe& kf,
                                    const lidar::LidarSweep& sweep, const std::vector<int>& indices,
                                    const Eigen::Vector3d& g_W, const sensors::Calibration& c) {
  return PointsInWorld(
      table, kf, sweep.t_ns, indices, g_W, c,
      [&](int i) { return Eigen::Vector3d(sweep.cloud.points.col(i)); },
      [&](int i) { return sweep.cloud.time_s(i); });
}

Eigen::Matrix3Xd SweepPointsInWorld(const ImuMotionTable& table, const Keyframe& kf,
                                    const SelectedSweep& sweep, const std::vector<int>& indices,
                                    const Eigen::Vector3d& g_W, const sensors::Calibration& c) {
  return PointsInWorld(
      table, kf, sweep.t_ns, indices, g_W, c, [&](int i) { return sweep.point(i); },
      [&](int i) { return sweep.time(i); });
}

double MaxPointMotion(const geometry::Pose3d& before, const geometry::Pose3d& after,
                      double range_m) {
  const geometry::Pose3d change = before.Inverse() * after;
  return change.p.norm() +
         geometry::AngularDistance(change.q, Eigen::Quaterniond::Identity()) * range_m;
}

namespace {

// Propagates the sweep with the current estimate and rebuilds its plane map when the deskew
// moved a map point by more than `rebuild_tolerance_m` (Eq. W1). The map holds the map
// points deskewed into L_j at the reference instant.
void RefreshMap(SweepFrame* f, const PairingUpdate& u, const PairingOptions& setting,
                double rebuild_tolerance_m) {
  const sensors::Calibration& c = *u.calibration;
  const double offset_s = c.time_offset_lidar_imu_s;
  const Keyframe& x = *f->s.state;
  const lidar::LidarSweep& sweep = *f->s.sweep;
  // The table covers the keyframe, the sweep's reference instant and its points at the offset
  // estimate (clamped to the IMU held).
  const ImuInterval table = MotionTableInterval(sweep.t_ns, f->s.span, offset_s, x.t_ns);
  const int64_t begin_ns = std::max(table.begin_ns, u.imu->front().t_ns);
  const int64_t end_ns = std::min(table.end_ns, u.imu->back().t_ns);
  // The offset's rate: the mean over a sweep's span about each point (Eq. P1b).
  f->table.emplace(*u.imu, begin_ns, end_ns, x.b_g, x.b_a, SecondsToNs(f->s.span.length_s()),
                   x.t_ns);
  f->reference_motion = f->MotionAt(0.0, offset_s);
  f->T_W_Lj = SweepLidarPose(x, f->reference_motion, u.g_W, c.q_I_L, c.p_I_L);
  f->T_Lj_W = f->T_W_Lj.Inverse();
  // The deskew's pose at the sweep's point farthest from its stamp, T_L0_L(tau_max).
  const geometry::Pose3d deskew_end =
      f->T_Lj_W *
      SweepLidarPose(x, f->MotionAt(f->s.span.farthest_s(), offset_s), u.g_W, c.q_I_L, c.p_I_L);
  SweepMap& map = *f->s.map;
  if (map.planes &&
      MaxPointMotion(map.deskew_end, deskew_end, map.max_range_m) <= rebuild_tolerance_m) {
    return;
  }
  const Eigen::Matrix3Xd points_W =
      SweepPointsInWorld(*f->table, x, sweep, *f->s.map_points, u.g_W, c);
  const Eigen::Matrix3Xd points_L =
      (f->T_Lj_W.q.toRotationMatrix() * points_W).colwise() + f->T_Lj_W.p;
  map.planes = std::make_unique<lidar::PlaneMap>(points_L, setting.plane_map);
  map.deskew_end = deskew_end;
  ++map.generation;
  map.max_range_m = 0.0;
  for (int i : *f->s.map_points) {
    map.max_range_m = std::max(map.max_range_m, sweep.cloud.points.col(i).norm());
  }
}
}  // namespace

SweepPairing::SweepPairing(const PairingOptions& pairing, const WindowPairingOptions& window,
                           const factors::LossOptions& point_loss, int num_threads)
    : pairing_(pairing), window_(window), point_loss_(point_loss), num_threads_(num_threads) {}

PairingResult SweepPairing::Pair(const std::vector<PairingSweep>& sweeps,
                                 const PairingUpdate& update) {
  std::vector<SweepFrame> frames;
  frames.reserve(sweeps.size());
  for (const PairingSweep& s : sweeps) frames.push_back({s, std::nullopt, {}, {}, {}});
  const int num_sweeps = static_cast<int>(frames.size());
  ParallelFor(0, num_sweeps, num_threads_, [&](int64_t begin, int64_t end, int) {
    for (int64_t k = begin; k < end; ++k) {
      RefreshMap(&frames[static_cast<size_t>(k)], update, pairing_,
                 window_.map_rebuild_tolerance_m);
    }
  });

  WalkContext ctx{pairing_, window_, point_loss_, frames, {}, update};
  for (int k = 0; k < num_sweeps; ++k) ctx.sweep_of_id[frames[static_cast<size_t>(k)].s.id] = k;
  // The gate widens while the extrinsic rotation moves.
  ctx.gate_per_range =
      window_.gate_extrinsic_factor *
      std::max(0.0, update.recent_rotation_rad - window_.gate_extrinsic_free_deg * kDegToRad);
  // The points try partner positions [0, S) first, the others after them; the points
  // of a keyframe first paired once the extrinsic rotation has settled only [0, S).
  ctx.settled_count =
      std::min(static_cast<size_t>(window_.settled_partner_count), pairing_.partner_offsets.size());
  ctx.settled = update.full_history &&
                update.recent_rotation_rad <= window_.settled_extrinsic_deg * kDegToRad;
  ctx.pool = &pool_;

  std::vector<int> lookups(static_cast<size_t>(num_sweeps), 0);
  pool_.SetChunks(std::max(num_threads_, 1));  // at least ParallelFor's chunks
  ParallelFor(0, num_sweeps, num_threads_, [&](int64_t begin, int64_t end, int chunk) {
    PointGroupPool::Storage& fresh_terms = pool_.Fresh(chunk);
    for (int64_t k = begin; k < end; ++k) {
      lookups[static_cast<size_t>(k)] = KeyframeWalk(ctx, static_cast<int>(k), &fresh_terms).Run();
    }
  });
  PairingResult result;
  result.extrinsic_settled = ctx.settled;
  for (int n : lookups) result.plane_lookups += n;
  return result;
}

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
