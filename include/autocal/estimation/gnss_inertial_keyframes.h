#pragma once

// Keyframe states from GNSS and the IMU alone (docs/keyframe_factors.md, "Keyframes from GNSS
// and the IMU"), for drives whose LiDAR odometry did not follow the car: a featureless road,
// or traffic moving with it, leaves the odometry's track metres short of the drive, and every
// state the initializer derives from it (velocities, gravity, the rotation about the vertical)
// with it.
//
// 1. Each keyframe is placed on the antenna track fitted to the fixes around it (Eq. K7,
//    PlaceKeyframesOnGnss), level and turned by the gyro's yaw about the vehicle's up axis
//    (their relative headings), then by one yaw from the track headings that stand out of the
//    fit's noise (Eqs. K8, K10) or, on a slow platform, from the track's travel (Eq. K11);
//    a keyframe with a trusted heading gets its vehicle x axis along it (Eq. K9), one without
//    keeps its gyro yaw relative to the trusted headings on either side (Eq. K9b), so that the
//    gyro bias's drift is that over the stretch without headings, not over the log (a stop
//    late in a long log started radians off, and past pi the solve kept it there).
// 2. A GNSS-inertial least-squares problem refines every state: IMU factors (Eq. F10) between
//    consecutive keyframes, GNSS factors (Eq. F30, Cauchy loss) on each keyframe (their std
//    scaled by their scatter where it exceeds the stated one, Eq. N2), wheel
//    factors (Eq. F22, F25 or F26: the form's) when wheel samples are given, and a weak prior on
//    the first keyframe's biases. Roll and pitch follow from gravity against the track's
//    acceleration. The yaw follows from the track only where the car accelerates sideways; on a
//    straight road the wheel factor's non-holonomic rows hold the vehicle's x axis along the track
//    (the form's scales, an odometry twist's effective track and q_I_V are estimated with the
//    states, q_I_V about its given value; p_I_V and a track width are held), and without wheels the
//    yaw drifts with the gyro bias.

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "autocal/estimation/keyframe.h"
#include "autocal/estimation/keyframe_sensor_factors.h"
#include "autocal/sensors/calibration.h"
#include "autocal/sensors/gnss_enu.h"
#include "autocal/sensors/measurements.h"
#include "autocal/sensors/sensor_config.h"

namespace autocal {
namespace estimation {

struct GnssInertialKeyframesOptions {
  GnssPlacementOptions placement;
  KeyframeGnssOptions gnss;    // loss and fix gap of the GNSS factors (the lever arm is held)
  KeyframeWheelOptions wheel;  // sigmas and loss of the wheel factors (blocks as above)
  sensors::ImuNoise imu_noise;
  double gravity_m_s2 = 9.80665;
  // 1-sigma of the prior on the first keyframe's biases at zero.
  double gyro_bias_prior_sigma_rad_s = 0.01;
  double accel_bias_prior_sigma_m_s2 = 0.3;
  // 1-sigma of the prior on q_I_V at its given value (used with wheel samples).
  double vehicle_rotation_prior_sigma_deg = 3.0;
  int max_iterations = 30;
  int num_threads = 1;
  // Also compute the first keyframe's covariance (GnssInertialKeyframes::first_covariance).
  bool first_keyframe_covariance = false;
  // GNSS noise from the residuals (estimation/gnss_noise.h, Eq. N2): about the solved states,
  // the fixes' scatter per axis group; where it exceeds their stated std, the states are solved
  // again with the std scaled by it, so that they and first_covariance weigh the fixes as they
  // scatter (an optimistic receiver otherwise gives the states a covariance several times too
  // small). false: gnss.noise_scale as given.
  bool gnss_noise_from_residuals = true;
};

struct GnssInertialKeyframes {
  GnssPlacement placement;
  int gnss_factors = 0;
  int wheel_factors = 0;
  double initial_cost = 0.0;
  double final_cost = 0.0;
  std::string termination;  // Ceres's message
  // With options.first_keyframe_covariance: the first keyframe's marginal covariance after the
  // solve, ordered [dphi (right perturbation of q_W_I), dp, dv, db_g, db_a] like a state prior
  // (Eq. F42); empty when the solve leaves a direction of it undetermined.
  std::optional<Eigen::Matrix<double, 15, 15>> first_covariance;
  // With options.gnss_noise_from_residuals: the fixes' scatter about the first solve, whitened
  // by their stated std.
  std::optional<GnssNoiseFromResiduals> gnss_noise;
  // What scaled the fixes' stated std in the solve the states come from.
  GnssStdScale gnss_std_scale;
};

// Replaces q, p, v, b_g, b_a of every keyframe (their times are kept) with the estimate from
// the fixes (as logged: the placement moves them onto the IMU clock by the calibration's GNSS
// time offset, the factors apply it), the IMU samples and the wheel samples of any form (may be
// empty); the calibration is used as given (its wheel blocks only as the start of their
// estimate; it is not changed).
// Throws autocal::Error as PlaceKeyframesOnGnss, for fewer than two keyframes, IMU samples that do
// not cover the keyframes, or a failed solve.
GnssInertialKeyframes KeyframesFromGnssAndImu(
    std::vector<Keyframe>* keyframes, const sensors::ImuSamples& imu, const WheelData& wheel,
    const sensors::GnssFixes& fixes, const sensors::EnuConverter& converter,
    const sensors::Calibration& calibration, const GnssInertialKeyframesOptions& options = {});

}  // namespace estimation
}  // namespace autocal
