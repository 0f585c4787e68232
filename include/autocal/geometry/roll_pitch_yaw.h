#pragma once

// Roll, pitch and yaw: the form in which the report and the summary show rotations
// (docs/report.md, "Result"). One representative per rotation, so that a rotation prints the
// same way however it was computed.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>

namespace autocal {
namespace geometry {

// Roll, pitch and yaw (radians) of R = Rz(yaw) Ry(pitch) Rx(roll) (ZYX: yaw about z, then
// pitch about the new y, then roll about the newest x). One representative of each
// rotation: pitch in [-pi/2, pi/2], roll and yaw in (-pi, pi] (an atan2 of -pi becomes pi).
// Where pitch is within 1e-9 rad of +-pi/2 (cos(pitch) below kGimbalLockCos) roll and yaw
// turn about the same axis and only their difference (pitch +pi/2) or sum (-pi/2) is
// determined: roll is then 0 and yaw carries the whole turn.
constexpr double kGimbalLockCos = 1e-9;

inline Eigen::Vector3d RollPitchYaw(const Eigen::Quaterniond& q) {
  const Eigen::Matrix3d R = q.normalized().toRotationMatrix();
  const auto wrap = [](double angle) { return angle <= -M_PI ? angle + 2.0 * M_PI : angle; };
  const double cos_pitch = std::hypot(R(0, 0), R(1, 0));
  const double pitch = std::atan2(-R(2, 0), cos_pitch);
  if (cos_pitch < kGimbalLockCos) {
    return Eigen::Vector3d(0.0, pitch, wrap(std::atan2(-R(0, 1), R(1, 1))));
  }
  return Eigen::Vector3d(wrap(std::atan2(R(2, 1), R(2, 2))), pitch,
                         wrap(std::atan2(R(1, 0), R(0, 0))));
}

// The rotation Rz(yaw) Ry(pitch) Rx(roll) (radians).
inline Eigen::Quaterniond FromRollPitchYaw(double roll, double pitch, double yaw) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                            Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                            Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()));
}

}  // namespace geometry
}  // namespace autocal
