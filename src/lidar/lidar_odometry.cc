#include "autocal/lidar/lidar_odometry.h"

#include <string>

#include "autocal/common/error.h"
#include "autocal/common/parallel_for.h"
#include "autocal/lidar/voxel_grid.h"

namespace autocal {
namespace lidar {

using Vector6d = Eigen::Matrix<double, 6, 1>;

namespace {

LocalVoxelMap MapOf(const LidarOdometryOptions& setting) {
  if (!(setting.voxel_m > 0.0) || setting.local_map_sweeps < 1 || setting.num_threads < 1) {
    throw Error("LidarOdometry: voxel_m must be > 0, local_map_sweeps >= 1 and num_threads >= 1");
  }
  return LocalVoxelMap(setting.voxel_m, setting.local_map_sweeps);
}

}  // namespace

LidarOdometry::LidarOdometry(LidarOdometryOptions setting)
    : setting_(std::move(setting)), map_(MapOf(setting_)) {
  setting_.icp.num_threads = setting_.num_threads;
}

Eigen::Matrix3Xd LidarOdometry::Deskewed(
    const PointCloud& grid, const Vector6d& velocity,
    const std::optional<Eigen::Vector3d>& angular_velocity) const {
  if (!setting_.deskew) return grid.points;
  Vector6d twist = velocity;
  if (angular_velocity) twist.tail<3>() = *angular_velocity;
  Eigen::Matrix3Xd out(3, grid.size());
  ParallelFor(0, grid.size(), setting_.num_threads, [&](int64_t begin, int64_t end, int) {
    for (int64_t i = begin; i < end; ++i) {
      // eq. (5.2): T_k_tau = Exp(xi tau) maps the point from the sensor frame at its firing
      // time into the frame at the sweep stamp.
      const Vector6d xi_tau = twist * grid.time_s(i);
      out.col(i) = geometry::ExpSE3(xi_tau) * Eigen::Vector3d(grid.points.col(i));
    }
  });
  return out;
}

LidarOdometry::SweepGrids LidarOdometry::Grids(const PointCloud& cloud) const {
  SweepGrids grids;
  grids.map = VoxelDownsample(cloud, setting_.voxel_m);
  grids.registration = setting_.registration_voxel_m > setting_.voxel_m
                           ? VoxelDownsample(grids.map, setting_.registration_voxel_m)
                           : grids.map;
  return grids;
}

Eigen::Matrix3Xd LidarOdometry::ToWorld(const Eigen::Matrix3Xd& points_L,
                                        const geometry::Pose3d& T_W_L) {
  return (T_W_L.R() * points_L).colwise() + T_W_L.p;
}

IcpTarget LidarOdometry::BuildMap(const LocalVoxelMap& map,
                                  const Eigen::Vector3d& viewpoint_W) const {
  NormalEstimationOptions normals = setting_.map_normals;
  normals.viewpoint = viewpoint_W;  // normals face the sensor at its last pose
  // Each map is registered against once or twice; most of its points never pair with a
  // sweep point, so their normals are not computed.
  return IcpTarget(map.Centroids(), TargetNormals::kOnDemand, normals, setting_.num_threads);
}

void LidarOdometry::TakeInPreviousSweep() {
  if (previous_sweep_W_.cols() == 0) return;  // taken in by a call that failed later
  map_.AddSweep(previous_sweep_W_);
  previous_sweep_W_.resize(3, 0);
}

const OdometryFrame& LidarOdometry::AddSweep(
    const LidarSweep& sweep, const std::optional<Eigen::Vector3d>& angular_velocity_L_rad_s) {
  CheckPointCloud(sweep.cloud, "LidarOdometry sweep");
  if (!frames_.empty() && sweep.t_ns <= frames_.back().t_ns) {
    throw Error("LidarOdometry: sweep stamp " + std::to_string(sweep.t_ns) +
                " ns is not after the previous one (" + std::to_string(frames_.back().t_ns) +
                " ns)");
  }
  if (sweep.cloud.empty()) {
    throw Error("LidarOdometry: the sweep at " + std::to_string(sweep.t_ns) +
                " ns holds no points");
  }
  if (setting_.deskew && !sweep.cloud.has_time()) {
    throw Error("LidarOdometry: deskewing needs per-point time, the sweep at " +
                std::to_string(sweep.t_ns) + " ns has none");
  }
  if (frames_.empty()) return AddFirstSweep(sweep, angular_velocity_L_rad_s);

  const OdometryFrame& previous = frames_.back();
  OdometryFrame frame;
  frame.t_ns = sweep.t_ns;
  const double dt_s = 1e-9 * static_cast<double>(sweep.t_ns - previous.t_ns);
  // The map takes in the previous sweep and is indexed while this sweep is gridded: the two
  // share nothing, and on one thread they run one after the other.
  SweepGrids grids;
  std::optional<IcpTarget> map;
  ParallelFor(0, 2, setting_.num_threads, [&](int64_t begin, int64_t end, int) {
    for (int64_t task = begin; task < end; ++task) {
      if (task == 0) {
        TakeInPreviousSweep();
        map.emplace(BuildMap(map_, previous.T_W_L.p));
      } else {
        grids = Grids(sweep.cloud);
      }
    }
  });
  // Two passes: the first deskews with the previous velocity, the second with the velocity
  // the first registration implies (the motion may have changed since the last sweep).
  // On the second sweep the first pass sees two sweeps distorted alike (no velocity yet),
  // which aligns them consistently; the map's first sweep is then deskewed as well, in a
  // copy of the one-sweep map that replaces it only when this call succeeds.
  Vector6d velocity = velocity_;
  std::optional<LocalVoxelMap> deskewed_first_map;
  geometry::Pose3d T_W_L = previous.T_W_L * geometry::ExpSE3(Vector6d(velocity * dt_s));  // (5.1)
  const int passes = setting_.deskew ? 2 : 1;
  for (int pass = 0; pass < passes; ++pass) {
    frame.icp = AlignIcp(Deskewed(grids.registration, velocity, angular_velocity_L_rad_s), *map,
                         T_W_L, setting_.icp);
    T_W_L = frame.icp.T_target_source;
    velocity = geometry::LogSE3(geometry::Pose3d(previous.T_W_L.Inverse() * T_W_L)) / dt_s;
    if (frames_.size() == 1 && setting_.deskew && pass == 0) {
      deskewed_first_map = map_;
      deskewed_first_map->ReplaceOldest(
          ToWorld(Deskewed(first_grid_, velocity, first_angular_velocity_), frames_[0].T_W_L));
      map.emplace(BuildMap(*deskewed_first_map, previous.T_W_L.p));
    }
  }
  frame.T_W_L = T_W_L;
  frame.T_prev_curr = previous.T_W_L.Inverse() * T_W_L;
  Eigen::Matrix3Xd sweep_W =
      ToWorld(Deskewed(grids.map, velocity, angular_velocity_L_rad_s), frame.T_W_L);
  // Every step that can fail is done: the call's effects from here on.
  frames_.push_back(frame);
  velocity_ = velocity;
  if (deskewed_first_map) {
    map_ = std::move(*deskewed_first_map);
    first_grid_ = PointCloud();
  }
  previous_sweep_W_ = std::move(sweep_W);
  return frames_.back();
}

const OdometryFrame& LidarOdometry::AddFirstSweep(
    const LidarSweep& sweep, const std::optional<Eigen::Vector3d>& angular_velocity_L_rad_s) {
  SweepGrids grids = Grids(sweep.cloud);
  OdometryFrame frame;
  frame.t_ns = sweep.t_ns;
  frame.T_W_L = setting_.initial_T_W_L;
  // No velocity yet: the first sweep enters the map (with the second) as measured and is
  // deskewed again once the second sweep has given a velocity.
  Eigen::Matrix3Xd sweep_W =
      ToWorld(Deskewed(grids.map, velocity_, angular_velocity_L_rad_s), frame.T_W_L);
  frames_.push_back(frame);
  first_grid_ = std::move(grids.map);
  first_angular_velocity_ = angular_velocity_L_rad_s;
  previous_sweep_W_ = std::move(sweep_W);
  return frames_.back();
}

}  // namespace lidar
}  // namespace autocal
