#pragma once

// The IMU's mounting in the vehicle, q_I_V (p_I = R_I_V p_V; V is x forward, y left, z up),
// from the data alone (docs/calibration.md, "IMU mount from gravity and motion"), so that a
// nominal guess may be far off or missing:
//   - the vehicle's up axis in the IMU frame is the direction of the mean specific force,
//     over a still period when the log has one, else over the samples that barely turn;
//   - its forward axis is the horizontal direction that best explains the horizontal specific
//     force by the wheel speed's derivative (forward) and the centripetal v * omega (left),
//     a least-squares rotation in the horizontal plane (with the IMU's horizontal lever arm
//     and a constant, Huber-weighted per window). The speed's sign gives the sign.
// The mount's roll and pitch are relative to the mean ground under the averaged samples, and
// the accelerometer's bias tilts them by bias / g (0.3 deg for 0.05 m/s^2).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "autocal/estimation/clock_offsets.h"
#include "autocal/estimation/initialization.h"
#include "autocal/sensors/measurements.h"

namespace autocal {
namespace estimation {

// The longest averaging window of the mount's horizontal fit: a minute averages a car's
// accelerations and turns away, and the fit needs ten windows.
constexpr double kMaxMountWindowS = 60.0;

struct MountInitializationOptions {
  StillStartOptions still;  // the still period that gives the up axis when there is one
  // Without a still period, samples turning slower than this give the up axis (no
  // centripetal acceleration), if they are at least a tenth of the log; else all samples.
  double max_low_dynamics_rate_rad_s = 0.05;
  double gravity_m_s2 = 9.80665;
  // A mean specific force further than this from gravity means a wrong unit or scale, or a
  // log that is mostly accelerating: the up axis is then not trusted.
  double max_gravity_error_m_s2 = 0.5;
  // Both sides of the horizontal fit are averaged over windows of this length (the
  // accelerometer's vibration, the speed's quantization), one fit row per window.
  // InitializeMount throws autocal::Error unless 0 < window_s <= kMaxMountWindowS.
  double window_s = 0.5;
  double min_excitation_m_s2 = 0.05;  // rms of the modelled horizontal acceleration
  // The fit's standard deviation about the up axis: an initial value only has to lie in
  // the solver's basin, which is far wider.
  double max_yaw_sigma_deg = 5.0;
  // The multiple correlation of the fit (explained share of the horizontal force's
  // variance, square-rooted); a skid-steer robot on rough ground reaches about 0.4.
  double min_fit_correlation = 0.3;
};

struct UpAxisEstimate {
  bool ok = false;
  std::string problem;                              // why not, when !ok
  Eigen::Vector3d up_I = Eigen::Vector3d::UnitZ();  // the vehicle's z axis in the IMU frame
  std::string source;                               // which samples were averaged
  double specific_force_m_s2 = 0.0;                 // |mean specific force| there
  size_t samples = 0;
  double span_s = 0.0;  // from the first to the last sample averaged
};

struct MountInitialization {
  bool ok = false;                    // up and forward axes both determined
  std::vector<std::string> problems;  // one sentence per problem
  // R_I_V = [forward_I, left_I, up_I]. Without a forward axis, the rotation with that up
  // axis closest to the identity's heading (q_I_V * z = up_I, yaw arbitrary).
  Eigen::Quaterniond q_I_V = Eigen::Quaterniond::Identity();
  UpAxisEstimate up;
  bool forward_found = false;
  Eigen::Vector3d forward_I = Eigen::Vector3d::UnitX();
  double yaw_sigma_deg = 0.0;    // standard deviation of the forward axis about up
  double fit_correlation = 0.0;  // modelled against measured horizontal force, centred
  double excitation_m_s2 = 0.0;  // rms of the modelled horizontal acceleration (centred)
  size_t windows = 0;            // fit rows
  // The IMU's horizontal position (forward, left) from the point the speed refers to, fitted
  // alongside (its centripetal and tangential accelerations in turns); rough, a by-product.
  Eigen::Vector2d lever_arm_m = Eigen::Vector2d::Zero();
};

// The up axis alone (it needs no wheel data and no time offset): what the wheel-IMU
// offset's yaw-rate comparison needs.
UpAxisEstimate EstimateUpAxis(const sensors::ImuSamples& imu,
                              const MountInitializationOptions& options = {});

// The whole mount. `wheel_speed_m_s` is the signed vehicle speed on the wheel clock,
// `wheel_time_offset_s` its offset (t_imu = t_wheel + offset, EstimateWheelImuOffset). The
// IMU is taken to sit near the rear axle: a lever arm r adds omega^2 r and d(omega)/dt x r,
// small on slow platforms.
MountInitialization InitializeMount(const sensors::ImuSamples& imu,
                                    const ScalarSeries& wheel_speed_m_s, double wheel_time_offset_s,
                                    const MountInitializationOptions& options = {});

// A Gaussian belief about the mount: q_I_V = q_centre Exp(delta), delta ~ N(0, diag(sigma^2)),
// delta = (roll, pitch, yaw) about the vehicle's axes (the right tangent, docs/design.md).
struct MountPrior {
  Eigen::Quaterniond q_I_V = Eigen::Quaterniond::Identity();
  Eigen::Vector3d sigma_rad = Eigen::Vector3d::Zero();
};

// The prior fused with gravity's up axis (docs/calibration.md, Eq. C4): up_I measures the
// mount's roll and pitch, R_I_V z = up_I, with standard deviation up_sigma_rad per axis (the
// mean ground's tilt under the averaged samples and the accelerometer's bias over g). In V at
// the prior's centre the measurement is delta_g = Log(FromTwoVectors(z, R_I_V^T up_I)), whose
// yaw is zero; roll and pitch combine as two Gaussians, the yaw keeps the prior's.
MountPrior FuseUpAxis(const MountPrior& prior, const Eigen::Vector3d& up_I, double up_sigma_rad);

}  // namespace estimation
}  // namespace autocal
