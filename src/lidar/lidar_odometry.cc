#include "autocal/lidar/lidar_odometry.h"

#include <string>

#include "autocal/common/error.h"
#include "autocal/common/parallel_for.h"
#include "autocal/lidar/voxel_grid.h"

namespace autocal {
namespace lidar {

using Vector6d = Eigen::Matrix<double, 6, 1>;

LidarOdometry::LidarOdometry(LidarOdometrySetting setting) : setting_(std::move(setting)) {
  if (!(setting_.voxel_m > 0.0) || setting_.local_map_sweeps < 1 || setting_.num_threads < 1) {
    throw Error("LidarOdometry: voxel_m must be > 0, local_map_sweeps >= 1 and num_threads >= 1");
  }
  setting_.icp.num_threads = setting_.num_threads;
}

Eigen::Matrix3Xd LidarOdometry::Deskew(
    const PointCloud& cloud, const std::optional<Eigen::Vector3d>& angular_velocity) const {
  Vector6d twist = velocity_;
  if (angular_velocity) twist.tail<3>() = *angular_velocity;
  Eigen::Matrix3Xd out(3, cloud.size());
  ParallelFor(0, cloud.size(), setting_.num_threads, [&](int64_t begin, int64_t end, int) {
    for (int64_t i = begin; i < end; ++i) {
      // eq. (5.2): T_k_tau = Exp(xi tau) maps the point from the sensor frame at its firing
      // time into the frame at the sweep stamp.
      const Vector6d xi_tau = twist * cloud.time_s(i);
      out.col(i) = geometry::ExpSE3(xi_tau) * Eigen::Vector3d(cloud.points.col(i));
    }
  });
  return out;
}

Eigen::Matrix3Xd LidarOdometry::ToWorld(const Eigen::Matrix3Xd& points_L,
                                        const geometry::Pose3d& T_W_L) {
  return (T_W_L.R() * points_L).colwise() + T_W_L.p;
}

Eigen::Matrix3Xd LidarOdometry::Downsampled(
    const PointCloud& cloud, const std::optional<Eigen::Vector3d>& angular_velocity) const {
  if (!setting_.deskew) return VoxelDownsample(cloud, setting_.voxel_m).points;
  PointCloud deskewed;
  deskewed.points = Deskew(cloud, angular_velocity);
  return VoxelDownsample(deskewed, setting_.voxel_m).points;
}

Eigen::Matrix3Xd LidarOdometry::RegistrationPoints(const Eigen::Matrix3Xd& points) const {
  if (!(setting_.registration_voxel_m > setting_.voxel_m)) return points;
  PointCloud cloud;
  cloud.points = points;
  return VoxelDownsample(cloud, setting_.registration_voxel_m).points;
}

IcpTarget LidarOdometry::BuildMap(const Eigen::Vector3d& viewpoint_W) const {
  int64_t total = 0;
  for (const Eigen::Matrix3Xd& part : map_sweeps_W_) total += part.cols();
  PointCloud map_cloud;
  map_cloud.points.resize(3, total);
  int64_t offset = 0;
  for (const Eigen::Matrix3Xd& part : map_sweeps_W_) {
    map_cloud.points.middleCols(offset, part.cols()) = part;
    offset += part.cols();
  }
  NormalEstimationSetting normals = setting_.map_normals;
  normals.viewpoint = viewpoint_W;  // normals face the sensor at its last pose
  // Each map is registered against once or twice; most of its points never pair with a
  // sweep point, so their normals are not computed.
  return IcpTarget(VoxelDownsample(map_cloud, setting_.voxel_m).points, TargetNormals::kOnDemand,
                   normals);
}

void LidarOdometry::AddToMap(const Eigen::Matrix3Xd& points_L, const geometry::Pose3d& T_W_L) {
  map_sweeps_W_.push_back(ToWorld(points_L, T_W_L));
  while (static_cast<int>(map_sweeps_W_.size()) > setting_.local_map_sweeps) {
    map_sweeps_W_.pop_front();
  }
}

const OdometryFrame& LidarOdometry::AddSweep(
    const LidarSweep& sweep, const std::optional<Eigen::Vector3d>& angular_velocity_L_rad_s) {
  CheckPointCloud(sweep.cloud, "LidarOdometry sweep");
  if (!frames_.empty() && sweep.t_ns <= frames_.back().t_ns) {
    throw Error("LidarOdometry: sweep stamp " + std::to_string(sweep.t_ns) +
                " ns is not after the previous one (" + std::to_string(frames_.back().t_ns) +
                " ns)");
  }
  if (setting_.deskew && !sweep.cloud.has_time()) {
    throw Error("LidarOdometry: deskewing needs per-point time, the sweep at " +
                std::to_string(sweep.t_ns) + " ns has none");
  }
  OdometryFrame frame;
  frame.t_ns = sweep.t_ns;
  if (frames_.empty()) {
    frame.T_W_L = setting_.initial_T_W_L;
    // No velocity yet: the first sweep enters the map as measured and is deskewed again
    // once the second sweep has given a velocity.
    first_sweep_ = sweep.cloud;
    first_angular_velocity_ = angular_velocity_L_rad_s;
    AddToMap(Downsampled(sweep.cloud, angular_velocity_L_rad_s), frame.T_W_L);
    frames_.push_back(frame);
    return frames_.back();
  }

  const OdometryFrame& previous = frames_.back();
  const double dt_s = 1e-9 * static_cast<double>(sweep.t_ns - previous.t_ns);
  std::optional<IcpTarget> map(BuildMap(previous.T_W_L.p));
  // Two passes: the first deskews with the previous velocity, the second with the velocity
  // the first registration implies (the motion may have changed since the last sweep).
  // On the second sweep the first pass sees two sweeps distorted alike (no velocity yet),
  // which aligns them consistently; the map's first sweep is then deskewed as well.
  geometry::Pose3d T_W_L =
      previous.T_W_L * geometry::ExpSE3(Vector6d(velocity_ * dt_s));  // eq. (5.1)
  Eigen::Matrix3Xd points;
  const int passes = setting_.deskew ? 2 : 1;
  for (int pass = 0; pass < passes; ++pass) {
    points = Downsampled(sweep.cloud, angular_velocity_L_rad_s);
    frame.icp = AlignIcp(RegistrationPoints(points), *map, T_W_L, setting_.icp);
    T_W_L = frame.icp.T_target_source;
    velocity_ = geometry::LogSE3(geometry::Pose3d(previous.T_W_L.Inverse() * T_W_L)) / dt_s;
    if (frames_.size() == 1 && setting_.deskew && pass == 0) {
      map_sweeps_W_.front() =
          ToWorld(Downsampled(first_sweep_, first_angular_velocity_), frames_[0].T_W_L);
      first_sweep_ = PointCloud();
      map.emplace(BuildMap(previous.T_W_L.p));
    }
  }
  frame.T_W_L = T_W_L;
  frame.T_prev_curr = previous.T_W_L.Inverse() * T_W_L;
  AddToMap(points, frame.T_W_L);
  frames_.push_back(frame);
  return frames_.back();
}

}  // namespace lidar
}  // namespace autocal
