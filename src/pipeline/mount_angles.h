#pragma once

// Rotations as people read them in the report and the summary: roll, pitch and yaw in
// degrees (geometry::RollPitchYaw), of the sensor's mounting in its parent frame, rounded
// for display. A rotation vector is not shown: near a half turn it jumps between opposite
// axes, so two nearly equal results printed as (-179.7, 0.0, 9.7) and (179.7, -0.35, -9.7).
// Private to src/pipeline.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>

#include "autocal/common/units.h"
#include "autocal/geometry/roll_pitch_yaw.h"
#include "autocal/geometry/so3.h"

namespace autocal {
namespace pipeline {

// The mounting whose angles are shown for a calibration rotation:
//   q_I_L -> R_I_L, the LiDAR in the IMU frame (angles about the IMU's axes);
//   q_I_V -> R_V_I, the IMU in the vehicle frame (roll about the vehicle's forward axis,
//            pitch about its left axis, yaw about its up axis).
inline Eigen::Quaterniond ImuMountInVehicle(const Eigen::Quaterniond& q_I_V) {
  return q_I_V.conjugate();
}

// Roll, pitch, yaw of `q` in degrees, rounded to `decimals`, such that nearly equal rotations
// print alike: an angle that rounds to -180 is shown as 180 (the ranges are (-180, 180]) and
// one that rounds to 0 as 0 (never "-0.0"). Near gimbal lock see geometry::RollPitchYaw.
inline Eigen::Vector3d DisplayRollPitchYawDeg(const Eigen::Quaterniond& q, int decimals) {
  const double scale = std::pow(10.0, decimals);
  Eigen::Vector3d out = geometry::RollPitchYaw(q) * kRadToDeg;
  for (int i = 0; i < 3; ++i) {
    double rounded = std::round(out(i) * scale) / scale;
    if (rounded <= -180.0) rounded += 360.0;
    if (rounded == 0.0) rounded = 0.0;  // drops the sign of -0
    out(i) = rounded;
  }
  return out;
}

}  // namespace pipeline
}  // namespace autocal
