#pragma once

// LiDAR odometry (docs/lidar.md §5): every sweep is deskewed, registered point-to-plane
// against a local map of the last sweeps, and added to that map.
//
//   predict  T_W_k = T_W_{k-1} Exp(xi dt)       constant velocity (eq. 5.1)
//   deskew   p_k = Exp(xi tau) p(tau)            each point into the frame at the sweep stamp
//                                                (eq. 5.2), or with the IMU rotation
//   register T_W_k = ICP(deskewed sweep -> local map, start T_W_k)
//   update   xi = Log(T_W_{k-1}^-1 T_W_k) / dt, append the sweep to the map
//
// Poses are T_W_L at each sweep's stamp (the time its points' time_s is relative to); W is
// the LiDAR frame of the first sweep unless an initial pose is given.

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <vector>

#include "autocal/geometry/se3.h"
#include "autocal/lidar/icp.h"
#include "autocal/lidar/local_voxel_map.h"
#include "autocal/lidar/normals.h"
#include "autocal/lidar/point_cloud.h"

namespace autocal {
namespace lidar {

struct LidarOdometryOptions {
  // Voxel edge for each incoming sweep and for the local map.
  double voxel_m = 0.25;
  // When larger than voxel_m, the sweep is registered with a coarser grid of its points
  // (the map keeps voxel_m): a few thousand well-spread points determine the pose as well
  // as all of them, at a fraction of the correspondence searches.
  double registration_voxel_m = 0.0;
  // Sweeps kept in the local map.
  int local_map_sweeps = 10;
  // Remove motion distortion within each sweep (needs per-point time).
  bool deskew = true;
  // Map normals from at most 1 m around a point so that corners do not blend faces.
  NormalEstimationOptions map_normals{10, 1.0, Eigen::Vector3d::Zero()};
  // Point-to-plane, Huber with 0.1 m scale: moving objects and map clutter are down-weighted.
  // Directions few correspondences constrain (a tunnel, a barrier-lined road) are reported
  // in IcpResult::weak_translations, the pose solved as usual: on simulated streets the few
  // correspondences beat the motion model (kHoldGuess; docs/lidar.md, "Degeneracy").
  IcpOptions icp = [] {
    IcpOptions setting;
    setting.robust = factors::RobustKernel{factors::RobustLoss::kHuber, 0.1};
    setting.degenerate = IcpDegenerate::kReport;
    return setting;
  }();
  geometry::Pose3d initial_T_W_L;
  // Threads for deskewing, map normals and registration (common/parallel_for.h); also
  // overrides icp.num_threads.
  int num_threads = 1;
};

struct OdometryFrame {
  int64_t t_ns = 0;
  geometry::Pose3d T_W_L;        // at the sweep stamp
  geometry::Pose3d T_prev_curr;  // relative motion from the previous sweep (identity first)
  IcpResult icp;                 // empty for the first sweep
};

class LidarOdometry {
 public:
  explicit LidarOdometry(LidarOdometryOptions setting = {});

  // Processes the next sweep (stamps strictly increasing). angular_velocity_L_rad_s, when
  // given, is the sensor's rate during the sweep (e.g. IMU gyro rotated into L) and replaces
  // the constant-velocity rotation for deskewing. Throws autocal::Error on a non-increasing
  // stamp, a sweep that fails CheckPointCloud, one without per-point time while deskewing, or
  // a failed registration. A call that throws leaves the odometry as it was: the next sweeps
  // are tracked as if the failed one had not been given.
  const OdometryFrame& AddSweep(
      const LidarSweep& sweep,
      const std::optional<Eigen::Vector3d>& angular_velocity_L_rad_s = std::nullopt);

  const std::vector<OdometryFrame>& frames() const { return frames_; }

 private:
  // A sweep's voxel grids in L, before deskewing: the centroids keep their points' mean time.
  struct SweepGrids {
    PointCloud map;           // voxel_m
    PointCloud registration;  // registration_voxel_m (the map grid when not coarser)
  };
  const OdometryFrame& AddFirstSweep(
      const LidarSweep& sweep, const std::optional<Eigen::Vector3d>& angular_velocity_L_rad_s);
  SweepGrids Grids(const PointCloud& cloud) const;
  // The grid's points in the frame at the sweep stamp (as they are without deskewing), for
  // the body-frame twist `velocity` (eq. 5.2).
  Eigen::Matrix3Xd Deskewed(const PointCloud& grid, const Eigen::Matrix<double, 6, 1>& velocity,
                            const std::optional<Eigen::Vector3d>& angular_velocity) const;
  IcpTarget BuildMap(const LocalVoxelMap& map, const Eigen::Vector3d& viewpoint_W) const;
  // Adds previous_sweep_W_ to map_, once.
  void TakeInPreviousSweep();
  static Eigen::Matrix3Xd ToWorld(const Eigen::Matrix3Xd& points_L, const geometry::Pose3d& T_W_L);

  LidarOdometryOptions setting_;
  std::vector<OdometryFrame> frames_;
  // Body-frame twist [v; w] per second from the last two poses (eq. 5.1).
  Eigen::Matrix<double, 6, 1> velocity_ = Eigen::Matrix<double, 6, 1>::Zero();
  LocalVoxelMap map_;
  // The last sweep's map grid in W: the map takes it in when the next sweep arrives, and it
  // is empty from then on (a sweep is never empty), also when that call fails afterwards:
  // the map holds the sweep then, as the call's retry would make it.
  Eigen::Matrix3Xd previous_sweep_W_;
  // The first sweep's grid is kept until a velocity is known to deskew it.
  PointCloud first_grid_;
  std::optional<Eigen::Vector3d> first_angular_velocity_;
};

}  // namespace lidar
}  // namespace autocal
