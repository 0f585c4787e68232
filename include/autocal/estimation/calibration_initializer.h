#pragma once

// The LiDAR-IMU initializer chain (docs/initialization.md): from raw IMU samples and LiDAR
// sweeps, without any extrinsic guess, to a calibration and keyframe states that the batch
// solver (lidar_inertial_batch.h) can start from.
//
//   1. LiDAR odometry           T_O_L per sweep (O = the first sweep's LiDAR frame)
//   2. still start              gyro bias, specific force at rest (else a low-excitation period)
//   3. time offset              rate-magnitude correlation over +-search range
//   4. hand-eye rotation        q_I_L from pairs of relative rotations ~1 s apart, the IMU's
//                               integrated over the offset-shifted intervals; then steps 1,
//                               3 and 4 once more with the sweeps deskewed by the gyro
//   5. inertial alignment       p_I_L, accel bias, gravity in O, a correction of q_I_L about
//                               the vertical (where the accelerations determine it) and one
//                               velocity per keyframe from a linear least-squares fit of IMU
//                               preintegration to odometry positions
//   6. keyframes                T_W_I = T_W_O T_O_L T_I_L^-1, W aligned with gravity
//
// Every step that the motion cannot support adds a plain-language problem to the result
// instead of producing numbers; the result is usable only when ok.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "autocal/common/units.h"
#include "autocal/estimation/initialization.h"
#include "autocal/estimation/keyframe.h"
#include "autocal/geometry/se3.h"
#include "autocal/lidar/lidar_odometry.h"
#include "autocal/lidar/point_cloud.h"
#include "autocal/lidar/sweep_source.h"
#include "autocal/sensors/measurements.h"
#include "autocal/sensors/sensor_config.h"

namespace autocal {
namespace estimation {

struct CalibrationInitializerOptions {
  // Step 1: scan-to-map odometry, constant-velocity deskewing (q_I_L is not known yet).
  lidar::LidarOdometryOptions odometry;
  // When the odometry fails at a sweep after at least this fraction of the log (a featureless
  // stretch), the chain runs on the sweeps before it and says so in `fallbacks`.
  double min_odometry_fraction = 0.5;
  // Step 2: the still start; when there is none, a low-excitation period (driving straight at
  // steady speed) found with the looser thresholds of `low_excitation` stands in for it.
  StillStartOptions still_start;
  StillStartOptions low_excitation = [] {
    StillStartOptions o;
    o.min_duration_s = 2.0;
    o.max_gyro_std_rad_s = 0.02;
    o.max_accel_std_m_s2 = 0.3;
    return o;
  }();
  // Step 3: offsets in [-0.1, 0.1] s are searched: the clocks are assumed to agree to
  // better than that, and a wider range only adds false peaks.
  TimeOffsetOptions time_offset = [] {
    TimeOffsetOptions o;
    o.search_range_s = 0.1;
    return o;
  }();
  // Step 4: a hand-eye pair joins sweep k to the first sweep at least this much later; long
  // pairs rotate more, so odometry noise tilts their rotation axes less.
  double hand_eye_pair_spacing_s = 1.0;
  // The hand-eye rotation needs at least this many pairs that rotated at least
  // min_pair_rotation_deg.
  double min_pair_rotation_deg = 5.0;
  int min_rotating_pairs = 10;
  HandEyeOptions hand_eye;
  // Repeat steps 1, 3 and 4 once with each sweep deskewed by the gyro (rotated into L with
  // the first q_I_L, at the first offset): constant-velocity deskewing lets the odometry lag
  // when the turn rate changes, which biases the offset (docs/history/initialization.md).
  bool gyro_deskew_pass = true;
  // With the gyro pass on, the first pass only has to find the offset and rotation to
  // deskew with, not their final values: it registers each sweep with this coarser grid
  // (LidarOdometryOptions::registration_voxel_m), which halves its cost.
  double first_pass_registration_voxel_m = 0.75;
  // Steps 3-4 on a drive that cannot determine them (no turns, e.g. a highway): with these
  // set, the chain goes on with the given value and says so in `fallbacks` instead of
  // stopping with a problem. Unset (the default), such a drive is a problem.
  std::optional<double> fallback_time_offset_s;
  std::optional<Eigen::Quaterniond> fallback_q_I_L;
  // Step 5: the lever arm's prior value; axes the motion does not excite keep it.
  Eigen::Vector3d p_I_L_prior = Eigen::Vector3d::Zero();
  // 1-sigma of the weak priors that keep the linear system regular: the lever arm about
  // p_I_L_prior and the accelerometer bias about zero.
  double p_I_L_prior_sigma_m = 1.0;
  double accel_bias_prior_sigma_m_s2 = 0.1;
  // 1-sigma of gravity in O as predicted from the rest period through q_I_L (0.05 m/s^2 is
  // ~0.3 deg of tilt): it keeps the odometry's slips from tilting gravity.
  double gravity_prior_sigma_m_s2 = 0.05;
  // 1-sigma of the zero velocity of keyframes inside the still start (not a low-excitation
  // period, where the vehicle moves).
  double rest_velocity_sigma_m_s = 0.01;
  // 1-sigma of an odometry position (ICP noise, drift over a sweep interval).
  double odometry_position_sigma_m = 0.02;
  // 1-sigma of an odometry orientation error; it tilts the IMU deltas against gravity.
  double odometry_rotation_sigma_rad = 0.002;
  // Odometry positions whose residual exceeds this many sigmas are down-weighted (Huber),
  // re-weighting this many times: LiDAR odometry slips along featureless streets.
  double huber_sigmas = 3.0;
  int robust_iterations = 5;
  // An IMU-frame axis of p_I_L counts as excited when its posterior standard deviation is
  // below this; otherwise it is held at p_I_L_prior.
  double max_excited_lever_arm_std_m = 0.03;
  // The rotation theta of q_I_L about the IMU's vertical is applied only when its posterior
  // standard deviation is below this; otherwise it is held at zero and `fallbacks` says so.
  // Planar driving leaves the hand-eye rotation 0.8-23 deg off about the vertical (simulated
  // urban drives of 28-120 s); a correction known to 0.5 deg (1.5 deg at three sigmas) improves
  // on that. Those drives determine theta to 0.15-0.33 deg; straight highway drives leave it
  // to 2-3 deg, where odometry slips rather than the rotation move it, and a straight drive at
  // steady speed to 100 deg and more (docs/initialization.md, "Rotation about the vertical").
  double max_vertical_rotation_std_rad = 0.5 * kDegToRad;
  // 1-sigma of the weak prior theta = 0 that keeps the linear system regular when the drive
  // has no horizontal acceleration at all (the theta column is then zero).
  double vertical_rotation_prior_sigma_rad = 1.0;
  // IMU noise densities for the preintegration weights.
  sensors::ImuNoise imu_noise;
  // Step 6: a sweep gets a keyframe when its points lie this far inside the IMU log at both
  // ends, room for a later solve to move the time offset.
  double offset_margin_s = 0.02;
  // A sweep whose keyframe would follow the last by less than this gets none.
  double min_keyframe_interval_s = 0.02;
};

// Step 5's estimate: the IMU preintegration fitted to the odometry.
struct InertialAlignment {
  Eigen::Vector3d p_I_L = Eigen::Vector3d::Zero();
  // Per IMU-frame axis: excited by the motion (else p_I_L holds the prior there).
  Eigen::Matrix<bool, 3, 1> excited = Eigen::Matrix<bool, 3, 1>::Constant(false);
  // Posterior standard deviation per axis with only the weak prior (before holding axes).
  Eigen::Vector3d lever_arm_std_m = Eigen::Vector3d::Zero();
  // Rotation of the hand-eye q_I_L about the IMU's vertical that the accelerations ask for
  // (planar driving leaves it to a few degrees of pitch and roll in the hand-eye step), and
  // whether it was determined (standard deviation below max_vertical_rotation_std_rad) and
  // applied; when not, the rotation is zero and q_I_L keeps the hand-eye (or fallback) value.
  double vertical_rotation_rad = 0.0;
  double vertical_rotation_std_rad = 0.0;  // with only the weak prior
  bool vertical_rotation_determined = false;
  Eigen::Vector3d accel_bias_m_s2 = Eigen::Vector3d::Zero();
  Eigen::Vector3d gravity_O_m_s2 = Eigen::Vector3d::Zero();  // gravity in the odometry frame
  double position_rms_m = 0.0;     // weighted RMS of the odometry-position residuals
  int downweighted_positions = 0;  // keyframe intervals the Huber weights discounted
};

struct CalibrationInitialization {
  bool ok = false;
  // Why the result is not usable, one plain-language sentence per problem.
  std::vector<std::string> problems;
  // Steps that the drive could not determine and that took the options' fallback values.
  std::vector<std::string> fallbacks;

  // Step 1: one frame per input sweep (T_W_L there is T_O_L here).
  std::vector<lidar::OdometryFrame> odometry;
  // Step 2.
  StillStart still_start;
  bool still_start_is_low_excitation = false;
  // Step 3: sweep-to-sweep LiDAR rotations (LiDAR clock) and the estimate.
  std::vector<RelativeRotation> sweep_rotations;
  TimeOffsetEstimate time_offset;
  // Step 4: the pairs of relative rotations that were aligned (IMU over the offset-shifted
  // interval, LiDAR between the two sweeps' odometry poses) and the solution.
  std::vector<Eigen::Quaterniond> hand_eye_imu_rotations;
  std::vector<Eigen::Quaterniond> hand_eye_lidar_rotations;
  HandEyeRotation rotation;
  // Step 5.
  InertialAlignment inertial;

  // The calibration (valid when ok): T_I_L (q_I_L from step 4 corrected in step 5) and
  // t_imu = t_lidar + time_offset_lidar_imu_s.
  Eigen::Quaterniond q_I_L = Eigen::Quaterniond::Identity();
  Eigen::Vector3d p_I_L = Eigen::Vector3d::Zero();
  double time_offset_lidar_imu_s = 0.0;

  // Step 6: the gravity-aligned world (z up, origin at the first keyframe's IMU position, its
  // yaw zero) from the odometry frame, and one keyframe per sweep listed in keyframe_sweeps
  // (indices into the input sweeps: those whose points lie inside the IMU log with
  // offset_margin_s), at KeyframeTime(sweep, offset): orientation from odometry and q_I_L,
  // velocity and position from step 5's fit, gyro bias from step 2, accel bias zero.
  geometry::Pose3d T_W_O;
  std::vector<int> keyframe_sweeps;
  std::vector<Keyframe> keyframes;
  // Sweeps left out of the keyframes: no IMU sample since the keyframe before (an IMU dropout,
  // sensors::ImuSampleBetween); the next keyframe spans the dropout.
  int keyframes_in_imu_dropouts = 0;
};

// Settings for a caller that refines the initializer's rotation and offset afterwards (the
// offline batch, the sliding window): the odometry runs once, without the gyro-deskewed
// repetition, registering each sweep on a 1 m grid of its points against a map on a 0.4 m
// grid (about 20 centroids of a plane within the 1 m of its normals) and stopping its ICP at
// steps below 1 mm and 0.1 mrad: a start the caller refines anyway (figures in
// docs/history/initialization.md, "Figures formerly in calibration_initializer.h").
CalibrationInitializerOptions RefinedLaterInitializerOptions();

// Runs the chain. Throws autocal::Error only on malformed input (unsorted stamps); poor
// motion or a failing odometry is reported in problems.
CalibrationInitialization InitializeLidarImu(const sensors::ImuSamples& imu,
                                             const std::vector<lidar::LidarSweep>& sweeps,
                                             const CalibrationInitializerOptions& options = {});
// The same on sweeps read as the odometry reaches them (each once, twice with
// gyro_deskew_pass), so that a long log is never held whole.
CalibrationInitialization InitializeLidarImu(const sensors::ImuSamples& imu,
                                             lidar::SweepSource* sweeps,
                                             const CalibrationInitializerOptions& options = {});

// Steps 2-6 on a given odometry (one frame per sweep, e.g. a previous result's `odometry`,
// which is gyro-deskewed): re-running with other options costs no registration. The
// odometry is used as it is (options.odometry and gyro_deskew_pass do not apply). Throws
// autocal::Error also when the odometry does not match the sweeps.
CalibrationInitialization InitializeLidarImuFromOdometry(
    const sensors::ImuSamples& imu, const std::vector<lidar::LidarSweep>& sweeps,
    const std::vector<lidar::OdometryFrame>& odometry,
    const CalibrationInitializerOptions& options = {});

}  // namespace estimation
}  // namespace autocal
