#include "import/ros_messages.h"

#include <cmath>
#include <cstring>
#include <optional>

namespace autocal {
namespace import {
namespace {

Eigen::Vector3d ReadVector3(MessageCursor* cursor) {
  Eigen::Vector3d v;
  v.x() = cursor->F64();
  v.y() = cursor->F64();
  v.z() = cursor->F64();
  return v;
}

// geometry_msgs/Quaternion: x, y, z, w.
Eigen::Quaterniond ReadQuaternion(MessageCursor* cursor) {
  const double x = cursor->F64();
  const double y = cursor->F64();
  const double z = cursor->F64();
  const double w = cursor->F64();
  return Eigen::Quaterniond(w, x, y, z);
}

// geometry_msgs/Twist: linear, angular.
void ReadTwist(MessageCursor* cursor, VehicleTwistMessage* twist) {
  const Eigen::Vector3d linear = ReadVector3(cursor);
  const Eigen::Vector3d angular = ReadVector3(cursor);
  twist->speed_m_s = linear.x();
  twist->yaw_rate_rad_s = angular.z();
}

// The smallest serialized size of a string (ROS 1: count; CDR: count and NUL).
size_t MinStringBytes(const MessageCursor& cursor) {
  return cursor.serialization() == Serialization::kCdr ? 5 : 4;
}

std::vector<double> ReadFloat64Sequence(MessageCursor* cursor) {
  const uint32_t count = cursor->SequenceCount(8);
  std::vector<double> values(count);
  for (double& value : values) value = cursor->F64();
  return values;
}

}  // namespace

std::string NormalizedTypeName(const std::string& type) {
  const size_t msg = type.find("/msg/");
  if (msg == std::string::npos) return type;
  return type.substr(0, msg) + "/" + type.substr(msg + 5);
}

MessageKind KindOfType(const std::string& type) {
  const std::string name = NormalizedTypeName(type);
  if (name == "sensor_msgs/Imu") return MessageKind::kImu;
  if (name == "sensor_msgs/PointCloud2") return MessageKind::kPointCloud2;
  if (name == "nav_msgs/Odometry") return MessageKind::kOdometry;
  if (name == "geometry_msgs/TwistStamped") return MessageKind::kTwistStamped;
  if (name == "sensor_msgs/JointState") return MessageKind::kJointState;
  if (name == "sensor_msgs/NavSatFix") return MessageKind::kNavSatFix;
  if (name == "tf2_msgs/TFMessage") return MessageKind::kTfMessage;
  return MessageKind::kOther;
}

const char* PointTimeFormName(PointTimeForm form) {
  switch (form) {
    case PointTimeForm::kNone:
      return "none";
    case PointTimeForm::kRelativeNsU32:
      return "t (uint32 ns)";
    case PointTimeForm::kRelativeSecondsF32:
      return "time (float32 s)";
    case PointTimeForm::kAbsoluteSecondsF64:
      return "timestamp (float64 absolute s)";
    case PointTimeForm::kOffsetNsU32:
      return "offset_time (uint32 ns)";
  }
  return "?";
}

ImuMessage DecodeImu(MessageCursor* cursor) {
  ImuMessage imu;
  imu.stamp_ns = cursor->Header(&imu.frame_id);
  ReadQuaternion(cursor);   // orientation
  cursor->SkipArray(9, 8);  // orientation_covariance
  imu.angular_velocity_rad_s = ReadVector3(cursor);
  cursor->SkipArray(9, 8);  // angular_velocity_covariance
  imu.linear_acceleration_m_s2 = ReadVector3(cursor);
  cursor->SkipArray(9, 8);  // linear_acceleration_covariance
  return imu;
}

VehicleTwistMessage DecodeOdometry(MessageCursor* cursor) {
  VehicleTwistMessage twist;
  twist.stamp_ns = cursor->Header(nullptr);
  twist.frame_id = std::string(cursor->String());  // child_frame_id: the twist's frame
  ReadVector3(cursor);                             // pose.pose.position
  ReadQuaternion(cursor);                          // pose.pose.orientation
  cursor->SkipArray(36, 8);                        // pose.covariance
  ReadTwist(cursor, &twist);                       // twist.twist
  cursor->SkipArray(36, 8);                        // twist.covariance
  return twist;
}

VehicleTwistMessage DecodeTwistStamped(MessageCursor* cursor) {
  VehicleTwistMessage twist;
  twist.stamp_ns = cursor->Header(&twist.frame_id);
  ReadTwist(cursor, &twist);
  return twist;
}

JointStateMessage DecodeJointState(MessageCursor* cursor) {
  JointStateMessage joints;
  joints.stamp_ns = cursor->Header(nullptr);
  const uint32_t names = cursor->SequenceCount(MinStringBytes(*cursor));
  joints.names.reserve(names);
  for (uint32_t i = 0; i < names; ++i) joints.names.emplace_back(cursor->String());
  joints.position_rad = ReadFloat64Sequence(cursor);
  joints.velocity_rad_s = ReadFloat64Sequence(cursor);
  ReadFloat64Sequence(cursor);  // effort
  return joints;
}

NavSatFixMessage DecodeNavSatFix(MessageCursor* cursor) {
  NavSatFixMessage fix;
  fix.stamp_ns = cursor->Header(&fix.frame_id);
  fix.status = cursor->I8();  // status.status
  cursor->U16();              // status.service
  fix.latitude_deg = cursor->F64();
  fix.longitude_deg = cursor->F64();
  fix.altitude_m = cursor->F64();
  for (double& c : fix.position_covariance_m2) c = cursor->F64();
  fix.covariance_type = cursor->U8();
  return fix;
}

std::vector<StampedTransform> DecodeTfMessage(MessageCursor* cursor) {
  // A TransformStamped takes at least a header, a string and 7 float64.
  const uint32_t count = cursor->SequenceCount(8 + 3 * MinStringBytes(*cursor) + 56);
  std::vector<StampedTransform> transforms(count);
  for (StampedTransform& transform : transforms) {
    transform.stamp_ns = cursor->Header(&transform.parent_frame);
    transform.child_frame = std::string(cursor->String());
    transform.T_parent_child.p = ReadVector3(cursor);
    const Eigen::Quaterniond q = ReadQuaternion(cursor);
    if (!(std::abs(q.norm() - 1.0) < 1e-3)) {
      cursor->Fail("transform " + transform.parent_frame + " -> " + transform.child_frame +
                   " has a quaternion of norm " + std::to_string(q.norm()) + ", not a rotation");
    }
    transform.T_parent_child.q = q.normalized();
  }
  return transforms;
}

}  // namespace import
}  // namespace autocal
