#pragma once

// Rotations as people read them in the report and the summary: roll, pitch and yaw in
// degrees (geometry::RollPitchYaw), of the sensor's mounting in its parent frame, rounded
// for display. A rotation vector is not shown: near a half turn it jumps between opposite
// axes, so two nearly equal results printed as (-179.7, 0.0, 9.7) and (179.7, -0.35, -9.7).
// Private to src/pipeline.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <vector>

#include "autocal/common/units.h"
#include "autocal/geometry/roll_pitch_yaw.h"
#include "autocal/geometry/so3.h"
#include "autocal/sensors/calibration_blocks.h"

namespace autocal {
namespace pipeline {

// The mounting whose angles are shown for a calibration rotation:
//   q_I_L -> R_I_L, the LiDAR in the IMU frame (angles about the IMU's axes);
//   q_I_V -> R_V_I, the IMU in the vehicle frame (roll about the vehicle's forward axis,
//            pitch about its left axis, yaw about its up axis).
inline Eigen::Quaterniond ImuMountInVehicle(const Eigen::Quaterniond& q_I_V) {
  return q_I_V.conjugate();
}

// The mounting a rotation block of `c` stands for: R_I_L for q_I_L, R_V_I for q_I_V.
inline Eigen::Quaterniond DisplayedMount(const sensors::CalibrationBlockInfo& info,
                                         const sensors::Calibration& c) {
  const double* v = info.const_values(c);
  const Eigen::Quaterniond q(v[3], v[0], v[1], v[2]);
  const bool vehicle = info.id == sensors::CalibrationBlockId::kVehicleRotation;
  return vehicle ? ImuMountInVehicle(q) : q;
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

// The sigma and observability of the angles DisplayRollPitchYawDeg shows, from the block's
// tangent ones. A calibration rotation's tangent is about the mounted frame's axes
// (docs/report.md): q_I_L's about the LiDAR's, R_I_L Exp(d), and q_I_V's about the vehicle's,
// Exp(-d) R_V_I (`about_parent_axes`). The angles move with it as G = d(roll, pitch, yaw) / dd:
// on a mount turned 90 deg in yaw the vehicle's forward axis moves the pitch, not the roll.
// Each angle's sigma is sqrt(sum_j G_ij^2 sigma_j^2) (a result carries no correlations between
// the axes), and it is observable when every axis that moves it (|G_ij| >= 0.1) is.
// `observable`: empty (every axis), one flag for all, or one per axis.
struct DisplayedAngles {
  Eigen::Vector3d sigma_deg = Eigen::Vector3d::Zero();
  std::vector<bool> observable = std::vector<bool>(3, true);  // per angle
};
inline DisplayedAngles DisplayedAngleUncertainty(const Eigen::Quaterniond& mount,
                                                 bool about_parent_axes,
                                                 const Eigen::Vector3d& tangent_sigma_deg,
                                                 const std::vector<bool>& observable) {
  constexpr double kStepRad = 1e-6;
  Eigen::Matrix3d G;
  for (int j = 0; j < 3; ++j) {
    const Eigen::Quaterniond turn = geometry::Exp(Eigen::Vector3d::Unit(j) * kStepRad);
    const Eigen::Quaterniond plus = about_parent_axes ? turn * mount : mount * turn;
    const Eigen::Quaterniond minus =
        about_parent_axes ? turn.conjugate() * mount : mount * turn.conjugate();
    const Eigen::Vector3d difference = geometry::RollPitchYaw(plus) - geometry::RollPitchYaw(minus);
    for (int i = 0; i < 3; ++i) {
      G(i, j) = std::remainder(difference(i), 2.0 * M_PI) / (2.0 * kStepRad);
    }
  }
  DisplayedAngles out;
  out.sigma_deg = (G.cwiseAbs2() * tangent_sigma_deg.cwiseAbs2()).cwiseSqrt();
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      const size_t axis = observable.size() == 1 ? 0 : static_cast<size_t>(j);
      const bool axis_observable = observable.empty() || observable[axis];
      if (std::abs(G(i, j)) >= 0.1 && !axis_observable)
        out.observable[static_cast<size_t>(i)] = false;
    }
  }
  return out;
}

}  // namespace pipeline
}  // namespace autocal
