#pragma once

// The calibration of a sensor rig: everything autocal estimates besides the trajectory.
// Frame names follow docs/design.md: I IMU, L LiDAR, V vehicle (rear-axle centre,
// x forward, y left, z up), A GNSS antenna.

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace autocal {
namespace sensors {

struct Calibration {
  // LiDAR-IMU extrinsic T_I_L: p_I = q_I_L * p_L + p_I_L.
  Eigen::Quaterniond q_I_L = Eigen::Quaterniond::Identity();
  Eigen::Vector3d p_I_L = Eigen::Vector3d::Zero();
  // t_imu = t_lidar + time_offset_lidar_imu_s.
  double time_offset_lidar_imu_s = 0.0;
  // Vehicle frame in the IMU frame, T_I_V.
  Eigen::Quaterniond q_I_V = Eigen::Quaterniond::Identity();
  Eigen::Vector3d p_I_V = Eigen::Vector3d::Zero();
  // Rear-wheel intrinsics.
  double wheel_radius_left_m = 0.33;
  double wheel_radius_right_m = 0.33;
  double track_width_m = 1.6;
  // Wheels reported as linear speeds (m/s): the true speed of a rear wheel is its scale times
  // the reported one (1 when the vehicle's own radius is right).
  double wheel_speed_scale_left = 1.0;
  double wheel_speed_scale_right = 1.0;
  // Wheels reported as the controller's speed and yaw rate (odometry twist): the true speed is
  // odometry_speed_scale (k_v) times the reported one, and the true yaw rate
  // k_v * yaw_rate_odo * b_ctrl / effective_track_m, b_ctrl being the separation the controller
  // divides by (sensors::WheelConfig::controller_track_m). A skid-steer platform slips in
  // turns, so its effective track b_eff exceeds the wheel separation.
  double odometry_speed_scale = 1.0;
  double effective_track_m = 1.6;
  // GNSS lever arm: antenna position in the IMU frame.
  Eigen::Vector3d p_I_A = Eigen::Vector3d::Zero();
  // Clocks of the wheel odometry and the GNSS receiver, as the LiDAR's:
  // t_imu = t_wheel + time_offset_wheel_imu_s, t_imu = t_gnss + time_offset_gnss_imu_s.
  double time_offset_wheel_imu_s = 0.0;
  double time_offset_gnss_imu_s = 0.0;
};

}  // namespace sensors
}  // namespace autocal
