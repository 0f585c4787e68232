#pragma once

// The blocks of a sensors::Calibration, described once. Every list of calibration blocks (the
// estimators' parameter blocks and priors, the covariance and uncertainty of a result, the
// columns of the result files) is derived from CalibrationBlocks() and keeps its order.

#include <array>
#include <string>
#include <vector>

#include "autocal/sensors/calibration.h"
#include "autocal/sensors/sensor_config.h"

namespace autocal {
namespace sensors {

// The blocks, in table order.
enum class CalibrationBlockId {
  kLidarRotation,         // q_I_L
  kLidarTranslation,      // p_I_L
  kTimeOffset,            // time_offset_lidar_imu_s
  kWheelRadiusLeft,       // wheel_radius_left_m
  kWheelRadiusRight,      // wheel_radius_right_m
  kTrackWidth,            // track_width_m
  kVehicleRotation,       // q_I_V
  kVehicleTranslation,    // p_I_V
  kGnssLeverArm,          // p_I_A
  kWheelSpeedScaleLeft,   // wheel_speed_scale_left
  kWheelSpeedScaleRight,  // wheel_speed_scale_right
  kOdometrySpeedScale,    // odometry_speed_scale
  kEffectiveTrack,        // effective_track_m
  kWheelTimeOffset,       // time_offset_wheel_imu_s
  kGnssTimeOffset,        // time_offset_gnss_imu_s
};
constexpr int kNumCalibrationBlocks = 15;

// How a block is perturbed: a unit quaternion [x, y, z, w] on the right, q ⊞ δ = q ⊗ Exp(δ)
// (geometry::RightQuaternionManifold; ambient 4, tangent 3 in rad), or a Euclidean vector.
enum class BlockManifold { kEuclidean, kRightQuaternion };

// The sensor whose data determines a block: without it the block cannot be estimated.
enum class BlockSensor { kLidar, kWheel, kGnss };

struct CalibrationBlockInfo {
  CalibrationBlockId id;
  const char* key;   // the field of Calibration and the block's name in files: "q_I_L"
  const char* name;  // in words: "T_I_L rotation", "track width"
  BlockSensor sensor;
  BlockManifold manifold;
  int ambient_size;  // doubles stored: 4 for a quaternion, else tangent_size
  int tangent_size;  // 3 or 1; tangent units are SI (rad, m, s)
  // Unit suffix of a vector's value columns ("m": p_I_L_x_m); empty for a quaternion and for
  // a scalar, whose key names its unit.
  const char* value_unit;
  // A tangent step times display_scale is in display_unit: rad -> deg, m -> cm or mm, s -> ms.
  double display_scale;
  const char* display_unit;
  std::array<const char*, 3> direction_names;  // the first tangent_size are used
  // Prefix of the block's columns in calibration_per_iteration.csv, whose names predate this
  // table ("q": qx, qy, qz, qw; "pv_": pv_x_m); empty for a scalar, whose column is its key.
  const char* iteration_column_prefix;
  double* (*values)(Calibration* calibration);  // the block's ambient_size doubles
  const double* (*const_values)(const Calibration& calibration);
};

// Every block, in CalibrationBlockId order.
const std::array<CalibrationBlockInfo, kNumCalibrationBlocks>& CalibrationBlocks();

const CalibrationBlockInfo& CalibrationBlock(CalibrationBlockId id);

// The block whose key is `key`, or nullptr.
const CalibrationBlockInfo* FindCalibrationBlock(const std::string& key);

// Whether the wheel data of `form` determine block `id`: the radii with angular rates, the speed
// scales with linear speeds, the track width with both, the odometry speed scale and the
// effective track with speed and yaw rate. Every other block (T_I_V among them) belongs to all.
bool BlockInWheelForm(CalibrationBlockId id, WheelForm form);

// Names of the block's ambient values as columns: "q_I_L_x" .. "q_I_L_w", "p_I_L_x_m",
// "time_offset_lidar_imu_s".
std::vector<std::string> ValueColumns(const CalibrationBlockInfo& block);

// The same in calibration_per_iteration.csv: "qx" .. "qw", "px_m", "time_offset_lidar_imu_s".
std::vector<std::string> IterationColumns(const CalibrationBlockInfo& block);

}  // namespace sensors
}  // namespace autocal
