#pragma once

// Options of the sliding-window estimator (sliding_window.h): what it estimates, its priors,
// and the nested options of its wheel rows, pairing, linearization and solver. The reasons behind
// the defaults are in docs/history/sliding_window_notes.md.

#include <Eigen/Core>
#include <map>
#include <optional>
#include <vector>

#include "autocal/estimation/estimated_blocks.h"
#include "autocal/estimation/gnss_noise.h"
#include "autocal/estimation/marginalization.h"
#include "autocal/estimation/pairing_options.h"
#include "autocal/factors/loss.h"
#include "autocal/sensors/body_rate.h"
#include "autocal/sensors/calibration.h"
#include "autocal/sensors/calibration_blocks.h"
#include "autocal/sensors/sensor_config.h"

namespace autocal {
namespace estimation {

// Which calibration blocks the window estimates; the others are held at their initial value.
struct SlidingWindowEstimatedBlocks : LidarEstimatedBlocks {
  bool wheel_radii = true;     // wheel_radius_left_m, wheel_radius_right_m
  bool track_width = true;     // track_width_m
  bool vehicle_frame = false;  // q_I_V, p_I_V (weakly observable from wheel data)
  bool gnss_lever_arm = true;  // p_I_A
  // Wheels as linear speeds (AddWheelSpeeds): wheel_speed_scale_left, wheel_speed_scale_right
  // (with track_width_m).
  bool wheel_speed_scales = true;
  // Wheels as the controller's speed and yaw rate (AddOdometry): odometry_speed_scale (k_v)
  // and effective_track_m (b_eff).
  bool odometry_speed_scale = true;
  bool effective_track = true;
};

// Priors (1-sigma) tying each estimated calibration block to `mean`; never marginalized, they
// regularize directions the first seconds of driving do not excite. `mean` unset: the initial
// calibration. A value estimated from the same log is no prior (it would count its data twice).
struct SlidingWindowCalibrationPrior {
  std::optional<sensors::Calibration> mean;
  double extrinsic_rotation_deg = 3.0;
  double extrinsic_translation_m = 0.1;
  double time_offset_s = 0.01;
  double wheel_radius_m = 0.01;
  double track_width_m = 0.05;
  double vehicle_rotation_deg = 2.0;
  double vehicle_translation_m = 0.1;
  double gnss_lever_arm_m = 0.2;
  double wheel_speed_scale = 0.03;     // dimensionless, each of the two
  double odometry_speed_scale = 0.03;  // dimensionless
  double effective_track_m = 0.5;
  // Per-axis sigmas of a three-axis block (the extrinsic and vehicle-frame rotations in
  // degrees, their translations and the GNSS lever arm in m), in its tangent order, replacing
  // its one sigma above: a lever arm measured in x and y but not in z, say.
  std::map<sensors::CalibrationBlockId, Eigen::Vector3d> axis_sigmas;
};

// 1-sigma of the prior on the initial state, which fixes the gauge until GNSS does.
struct SlidingWindowInitialStateSigmas {
  double rotation_deg = 0.01;
  double position_m = 0.001;
  double velocity_m_s = 0.01;
  double gyro_bias_rad_s = 2e-3;
  double accel_bias_m_s2 = 3e-2;

  // The 15 sigmas in the state prior's order [dphi (rad), dp, dv, db_g, db_a] (Eq. F42).
  Eigen::Matrix<double, 15, 1> InStatePriorOrder() const;
};

// The wheel rows (docs/sliding_window.md, "Wheel rows"): speed and yaw rate whitened with
// the encoder and gyro noise, optionally the rear axle's lateral and vertical speed.
struct WheelRowOptions {
  // Non-holonomic rows; their sigmas are scaled for the model error's correlation time
  // (NonHolonomicSigmaScale) at the spacing of the samples used (correlation 0: white rows).
  // The lateral row's is the rear axle's slip that SlidingWindowOptions::wheel states (Eq. K6c),
  // the vertical row's this.
  bool non_holonomic = false;
  double vertical_sigma_m_s = 0.05;
  double non_holonomic_correlation_s = 2.0;
  int max_samples_per_interval = 5;  // evenly spread; 0: all
  // The angular rate the rows take: the mean gyro over this span around the sample (0: the
  // gyro interpolated at the sample), which keeps gyro noise out of the lever-arm regressor.
  double gyro_mean_span_s = 0.05;
  // The yaw-rate rows read the body rate about the axis the vehicle turns about, measured from
  // the keyframes' rates streamed so far (Eq. K13c of docs/keyframe_factors.md), once that
  // axis's standard error is below this; until then, and with 0, about V's up axis through
  // q_I_V, whose tilt error e lengthens the track by b e^2 / 2.
  double max_turning_axis_error_deg = 1.0;
  // Planar-rotation rows (Eq. F27): one per keyframe, on its b_g and q_I_V, with this sigma of
  // the roll and pitch rates in V (PlanarRotationSpread::RowSigmaRadS); zero: no such rows.
  double planar_rotation_sigma_rad_s = 0.0;
  // The spread of the log's body rates (Eq. K14): with it the rows take the rate given the
  // gyro mean instead of the mean itself (whose noise would pass for excitation of the lever
  // arm and the mount's tilt), and its remaining error enters their sigmas (Eq. K13).
  std::optional<sensors::BodyRatePrior> body_rate_prior;
};

// Rows linearized per solve pass (docs/sliding_window.md, "Linearized once per pass").
struct LinearizationOptions {
  // Passes per update: the first on every point group, wheel and GNSS row linearized afresh,
  // a later one on the groups that moved. 0: one pass evaluating them at every iteration.
  int passes_per_update = 2;
  // A further pass runs only when some group's points moved by more than this since its
  // linearization (0: always passes_per_update passes).
  double relinearization_tolerance_m = 0.01;
};

// The window's Levenberg-Marquardt (docs/sliding_window.md, "Solver"; Eq. W5).
struct WindowSolverOptions {
  // Iterations (accepted and rejected steps) per pass at most.
  int max_iterations = 10;
  // Stop once an accepted step lowers the cost by less than this fraction of it.
  double function_tolerance = 1e-5;
  // Stop when the largest gradient entry is below this, or the step below this fraction of
  // |delta|.
  double gradient_tolerance = 1e-10;
  double parameter_tolerance = 1e-8;
  // Levenberg-Marquardt damping: (H + diag(H) / radius) step = -g.
  double initial_trust_region_radius = 1e4;
};

struct SlidingWindowOptions {
  int window_size = 10;  // keyframes kept: every sweep or AddKeyframeAt time makes one
  sensors::ImuConfig imu;
  sensors::WheelConfig wheel;
  factors::FactorLossOptions loss;  // per sensor, on whitened residuals
  SlidingWindowEstimatedBlocks estimate;
  SlidingWindowCalibrationPrior calibration_prior;
  SlidingWindowInitialStateSigmas initial_state_sigmas;
  // The initial state's covariance, ordered [dphi, dp, dv, db_g, db_a] as the state prior
  // (Eq. F42), when an initializer knows it (a GNSS-inertial start); it replaces
  // initial_state_sigmas. Must be symmetric positive definite.
  std::optional<Eigen::Matrix<double, 15, 15>> initial_state_covariance;
  WheelRowOptions wheel_rows;
  // Origin of W for AddGnss(GnssFix) (latitude, longitude, ellipsoidal height); unset: the ENU
  // frame at the first fix, so the initial state must be given in that frame.
  std::optional<Eigen::Vector3d> enu_origin_lla;
  // A keyframe sits at its sweep's middle (KeyframeTime); a sweep is processed once the IMU
  // covers its last point plus imu_coverage_margin_s; one whose keyframe would follow the
  // newest by less than min_keyframe_interval_s is dropped as late.
  double imu_coverage_margin_s = 0.02;
  double min_keyframe_interval_s = 0.02;
  PairingOptions pairing = WindowPairingDefaults(window_size);  // offsets beyond the window unused
  WindowPairingOptions window_pairing;
  LinearizationOptions linearization;
  WindowSolverOptions solver;
  int num_threads = 1;  // the pairing's loops and the covariance; the solve runs on one
  MarginalizationOptions marginalization;
  // Keep each marginalized keyframe's conditional (about 12 KB each) for SmoothedTrajectory().
  bool smoothing = false;
  // GNSS noise from the residuals (estimation/gnss_noise.h, Eq. N2): the GNSS rows of every
  // keyframe the window marginalizes, whitened by the fixes' stated std at the estimate it
  // leaves with; from kMinGnssNoiseRows of them on, every fix attached later has its std
  // scaled by what they show (SlidingWindowEstimator::gnss_noise). The rows already in the
  // marginalization prior keep the std they were weighed with. false: gnss_std_scale.
  bool gnss_noise_from_residuals = true;
  // What scales the fixes' stated std until the window's own rows judge an axis group (above),
  // e.g. the scatter of the fixes the start was fitted to (GnssInertialKeyframes::gnss_std_scale).
  GnssStdScale gnss_std_scale;
  // Blocks held at their value (not estimated) whose information the window carries through
  // a second marginalization, so that FixedDirectionsTheStreamMoves can test them against the
  // whole stream (docs/sliding_window.md, "Fixed blocks"); the estimate does not depend on it.
  // Empty: no second marginalization.
  std::vector<sensors::CalibrationBlockId> tested_fixed_blocks;
};

}  // namespace estimation
}  // namespace autocal
