#pragma once

// A calibration result in the files of the stacks that consume it (docs/export.md holds each
// format's frames, time-offset sign and source):
//   kalibr          Kalibr's camchain style: T_lidar_imu, the 4x4 that takes IMU coordinates
//                   to LiDAR coordinates (T_L_I), and timeshift_lidar_imu (t_imu = t_lidar +
//                   shift, Kalibr's sign for timeshift_cam_imu);
//   fast_lio        FAST-LIO's config: mapping.extrinsic_T and extrinsic_R (row-major), the
//                   LiDAR in the IMU frame (T_I_L), and common.time_offset_lidar_to_imu (FAST-LIO
//                   subtracts it from the IMU stamps: t_imu = t_lidar + offset);
//   lio_sam         LIO-SAM's params: extrinsicRot (= extrinsicRPY) R_L_I and extrinsicTrans
//                   p_L_I, i.e. T_L_I ("lidar -> IMU" in its file); no time offset field;
//   autoware        Autoware's sensor kit calibration: each sensor frame in base_link (on the
//                   ground under the rear axle) as x, y, z (m) and roll, pitch, yaw (rad);
//   urdf            fixed joints, each sensor's origin xyz and rpy in its parent link;
//   ros2_static_tf  one `ros2 run tf2_ros static_transform_publisher` command per sensor.
// Angles are those of R = Rz(yaw) Ry(pitch) Rx(roll) (URDF's fixed-axis rpy, geometry::
// RollPitchYaw). The frames are the blocks the result estimated: the LiDAR when T_I_L has a
// sigma, the vehicle when T_I_V has, the antenna when p_I_A has; a format that needs a frame
// the result lacks is refused.

#include <optional>
#include <string>

#include "autocal/io/calibration_yaml.h"

namespace autocal {
namespace io {

enum class ExportFormat { kKalibr, kFastLio, kLioSam, kAutoware, kUrdf, kRos2StaticTf };

// "kalibr", "fast_lio", "lio_sam", "autoware", "urdf", "ros2_static_tf". Throws autocal::Error
// naming the known formats otherwise.
ExportFormat ParseExportFormat(const std::string& name);

struct ExportOptions {
  std::string vehicle_frame = "base_link";
  std::string imu_frame = "imu_link";
  std::string lidar_frame = "lidar_link";
  std::string gnss_frame = "gnss_link";
  // How far the vehicle frame of the export lies below the rear-axle centre (autocal's V
  // origin). Autoware's base_link is on the ground: unset, the mean calibrated rear wheel
  // radius is used when the result estimated the radii, else 0 (and the file says so).
  std::optional<double> base_link_below_axle_m;
};

// The file's text. Throws autocal::Error when the format needs a frame the result lacks
// (kalibr, fast_lio and lio_sam: the LiDAR; autoware: the vehicle).
std::string ExportCalibration(const CalibrationFile& result, ExportFormat format,
                              const ExportOptions& options = {});

}  // namespace io
}  // namespace autocal
