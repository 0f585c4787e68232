#pragma once

// Keyframe states without a position reference (docs/keyframe_factors.md, "Keyframes by dead
// reckoning"), for logs with the IMU and the wheels alone: the first keyframe sits at the
// origin with yaw zero; each keyframe is level and turned by the gyro's yaw about the vehicle's
// up axis, R_W_I = R_z(psi_k) R_V_I (Eq. K12); it moves at the wheel speed along the vehicle's
// x axis, with the IMU's turn about it, v_W_I = R_z(psi_k) (v_k, 0, 0) - R_W_I (w_k x p_I_V)
// (w_k the gyro at the keyframe); positions follow by the trapezoid rule between
// keyframes. Biases start at zero. A solve with the IMU and wheel factors refines them, with
// the first keyframe's position and yaw as the gauge (AddDeadReckoningGauge): nothing in such a
// log observes where the platform is or which way it faces.

#include <ceres/ceres.h>

#include <Eigen/Geometry>
#include <vector>

#include "autocal/estimation/clock_offsets.h"
#include "autocal/estimation/keyframe.h"
#include "autocal/sensors/measurements.h"

namespace autocal {
namespace estimation {

// Sets q, p, v, b_g and b_a of every keyframe (their times are kept). `speed_m_s` is the
// vehicle's signed speed on the IMU clock (interpolated, clamped at its ends). Throws
// autocal::Error for fewer than two keyframes, IMU samples that do not cover them or an empty
// speed series.
void PlaceKeyframesByDeadReckoning(std::vector<Keyframe>* keyframes, const sensors::ImuSamples& imu,
                                   const ScalarSeries& speed_m_s, const Eigen::Quaterniond& q_I_V,
                                   const Eigen::Vector3d& p_I_V);

// The gauge of a log without a position reference: the first keyframe's position (sigma
// position_sigma_m per axis) and its rotation about the world's vertical (sigma yaw_sigma_rad)
// held where they are. The keyframe's q_W_I and p_W_I must be parameter blocks of `problem`.
void AddDeadReckoningGauge(ceres::Problem* problem, Keyframe* first, double position_sigma_m,
                           double yaw_sigma_rad);

}  // namespace estimation
}  // namespace autocal
