#pragma once

// Decoders of the ROS messages autocal imports, for both serializations (ROS 1 and CDR,
// see message_cursor.h). Each reads exactly the message's fields in order and returns what
// the dataset needs; a message shorter than its type is a ParseError (docs/import.md,
// "Message mapping"). Private to src/import.

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "autocal/geometry/se3.h"
#include "autocal/lidar/point_cloud.h"
#include "import/message_cursor.h"

namespace autocal {
namespace import {

enum class MessageKind {
  kImu,           // sensor_msgs/Imu
  kPointCloud2,   // sensor_msgs/PointCloud2
  kOdometry,      // nav_msgs/Odometry
  kTwistStamped,  // geometry_msgs/TwistStamped
  kJointState,    // sensor_msgs/JointState
  kNavSatFix,     // sensor_msgs/NavSatFix
  kTfMessage,     // tf2_msgs/TFMessage
  kOther,
};

// The kind of a stored type name, ROS 1 ("sensor_msgs/Imu") or ROS 2 ("sensor_msgs/msg/Imu").
MessageKind KindOfType(const std::string& type);
// "sensor_msgs/msg/Imu" -> "sensor_msgs/Imu"; other names unchanged.
std::string NormalizedTypeName(const std::string& type);

struct ImuMessage {
  int64_t stamp_ns = 0;
  std::string frame_id;
  Eigen::Vector3d angular_velocity_rad_s = Eigen::Vector3d::Zero();
  Eigen::Vector3d linear_acceleration_m_s2 = Eigen::Vector3d::Zero();
};

// Vehicle speed and yaw rate from nav_msgs/Odometry (twist in child_frame_id) or
// geometry_msgs/TwistStamped: linear.x and angular.z.
struct VehicleTwistMessage {
  int64_t stamp_ns = 0;
  std::string frame_id;
  double speed_m_s = 0.0;
  double yaw_rate_rad_s = 0.0;
};

struct JointStateMessage {
  int64_t stamp_ns = 0;
  std::vector<std::string> names;
  std::vector<double> position_rad;
  std::vector<double> velocity_rad_s;
};

struct NavSatFixMessage {
  int64_t stamp_ns = 0;
  std::string frame_id;
  int8_t status = 0;  // < 0: no fix
  double latitude_deg = 0.0;
  double longitude_deg = 0.0;
  double altitude_m = 0.0;
  std::array<double, 9> position_covariance_m2{};  // ENU, row-major
  uint8_t covariance_type = 0;  // 0 unknown, 1 approximated, 2 diagonal known, 3 known
};

// One transform of a tf2_msgs/TFMessage: T_parent_child.
struct StampedTransform {
  int64_t stamp_ns = 0;
  std::string parent_frame;
  std::string child_frame;
  geometry::Pose3d T_parent_child;
};

// How a PointCloud2 carries per-point time (docs/import.md, "Point time").
enum class PointTimeForm {
  kNone,                // no time field: every point gets t = 0
  kRelativeNsU32,       // `t` uint32, ns after the header stamp (Ouster)
  kRelativeSecondsF32,  // `time` float32, s relative to the header stamp (Velodyne)
  kAbsoluteSecondsF64,  // `timestamp` float64, absolute s (Hesai, RoboSense)
  kOffsetNsU32,         // `offset_time` uint32, ns after the header stamp (Livox)
};
const char* PointTimeFormName(PointTimeForm form);

struct PointCloudMessage {
  int64_t stamp_ns = 0;
  std::string frame_id;
  uint32_t height = 0;
  uint32_t width = 0;
  PointTimeForm time_form = PointTimeForm::kNone;
  // Points with a finite, non-zero position; time_s relative to stamp_ns; intensity when
  // the cloud has an `intensity` field.
  lidar::PointCloud cloud;
  int64_t dropped_points = 0;  // non-finite or (0, 0, 0): no return
};

ImuMessage DecodeImu(MessageCursor* cursor);
VehicleTwistMessage DecodeOdometry(MessageCursor* cursor);
VehicleTwistMessage DecodeTwistStamped(MessageCursor* cursor);
JointStateMessage DecodeJointState(MessageCursor* cursor);
NavSatFixMessage DecodeNavSatFix(MessageCursor* cursor);
std::vector<StampedTransform> DecodeTfMessage(MessageCursor* cursor);
PointCloudMessage DecodePointCloud2(MessageCursor* cursor);

}  // namespace import
}  // namespace autocal
