#pragma once

// Calibration problem files (problems/README.md): what one calibration run solves for.
//
//   description: "urban drive, every sensor, every block"   # optional, free text
//   sensors: {lidar: true, wheel: true, gnss: true}          # the IMU always takes part
//   calibration:
//     T_I_L: {rotation: estimate, translation: {prior_sigma_m: [0.05, 0.05, 0.02]}}
//     time_offset_lidar_imu_s: estimate                     # or fixed, {prior_sigma_s: 0.005}
//     wheel_radius_left_m: estimate                         # or {prior_sigma_m: 0.002}
//     wheel_radius_right_m: estimate
//     wheel_radius_shared: false                            # true: one radius for both wheels
//     track_width_m: {prior_sigma_m: 0.02}
//     p_I_A_m: estimate
//     T_I_V: {rotation: fixed, translation: fixed}          # rotation priors: prior_sigma_deg
//     wheel_speed_scale_left: estimate                      # wheels as linear speeds
//     wheel_speed_scale_right: {prior_sigma: 0.01}          # (dimensionless)
//     odometry_speed_scale: estimate                        # wheels as speed and yaw rate
//     effective_track_m: {prior_sigma_m: 0.2}
//     time_offset_wheel_imu_s: estimate                     # default fixed (at the nominal)
//     time_offset_gnss_imu_s: {prior_sigma_s: 0.05}         # default fixed (at the nominal)
//   loss: {imu: none, prior: none, wheel: "huber:2", gnss: "cauchy:3", lidar: "huber:1"}
//   window: {size: 10, max_range_m: 40}
//   solver: {max_iterations: 15, outer_iterations: 8, num_threads: 1}
//   lidar: {max_points_per_sweep: 400, voxel_m: 0.6, sweep_stride: 1}
//   timing: {max_wheel_gap_s: 0.25, keyframe_period_s: 0.4, min_factor_fraction: 0.5}
//
// Numbers must lie in a physically sensible range (problems/README.md): prior sigmas within
// [1e-6, 180] deg, [1e-6, 100] m, [1e-9, 10] s; voxel_m within [0.01, 20] m; max_range_m 0 or
// within [1, 10000] m.
//
// Every key is optional and takes the default of the structs below. A sensor that does not
// take part holds its calibration blocks fixed; setting one of those blocks (or the sensor's
// loss, or the lidar section without the LiDAR) is an error, since it would have no effect.
// Unknown keys, wrong types, bad enum values and out-of-range numbers are ParseErrors with
// file, line and column.

#include <Eigen/Core>
#include <optional>
#include <string>

#include "autocal/factors/loss.h"
#include "autocal/io/dataset.h"

namespace autocal {
namespace io {

// How a calibration block enters the problem.
enum class BlockMode {
  kEstimate,  // free parameter, starts at the initial guess
  kFixed,     // held constant at the initial guess
  kPrior,     // free, with a Gaussian prior of the given sigma centred on the initial guess
};

// "estimate", "fixed" or "prior".
const char* BlockModeName(BlockMode mode);

// A one-dimensional block (time offset, a wheel radius, the track width). prior_sigma is in
// the block's unit (s or m) and is > 0 exactly when mode is kPrior.
struct ScalarBlockSetting {
  BlockMode mode = BlockMode::kEstimate;
  double prior_sigma = 0.0;
};

// A three-dimensional block: a translation or lever arm (sigma per axis in m), or a rotation
// (sigma in degrees about the block's own axes, the right perturbation q = q0 ⊗ Exp(δ) of
// docs/design.md). prior_sigma is > 0 on every axis exactly when mode is kPrior.
struct VectorBlockSetting {
  BlockMode mode = BlockMode::kEstimate;
  Eigen::Vector3d prior_sigma = Eigen::Vector3d::Zero();
};

struct PoseBlockSetting {
  VectorBlockSetting rotation;     // prior_sigma in degrees
  VectorBlockSetting translation;  // prior_sigma in metres
};

// Which sensors take part besides the IMU (which always does).
struct ProblemSensors {
  bool lidar = true;
  bool wheel = true;
  bool gnss = true;
};

// Every block defaults to kEstimate. The LiDAR owns T_I_L and the time offset, the wheel
// encoders own both radii, the track width and T_I_V (wheel odometry lives in V), the GNSS
// receiver owns the lever arm. Of the wheel intrinsics only those of the dataset's wheel form
// take part (sensors::BlockInWheelForm): radii and track width for angular rates, speed
// scales and track width for linear speeds, odometry speed scale and effective track for
// speed and yaw rate; the settings of the others are ignored. The wheel and GNSS clocks
// (time_offset_wheel_imu_s, owned by the wheels, time_offset_gnss_imu_s, by the GNSS receiver)
// default to kFixed at the nominal offset: a problem estimates them only when it says so.
struct ProblemCalibration {
  PoseBlockSetting T_I_L;
  ScalarBlockSetting time_offset_lidar_imu_s;
  ScalarBlockSetting wheel_radius_left_m;
  ScalarBlockSetting wheel_radius_right_m;
  // One radius r = r_l = r_r for both rear wheels; the left and right settings are then equal.
  bool wheel_radius_shared = false;
  ScalarBlockSetting track_width_m;
  VectorBlockSetting p_I_A_m;
  PoseBlockSetting T_I_V;
  ScalarBlockSetting wheel_speed_scale_left;  // prior_sigma dimensionless
  ScalarBlockSetting wheel_speed_scale_right;
  ScalarBlockSetting odometry_speed_scale;  // prior_sigma dimensionless
  ScalarBlockSetting effective_track_m;
  ScalarBlockSetting time_offset_wheel_imu_s{BlockMode::kFixed, 0.0};
  ScalarBlockSetting time_offset_gnss_imu_s{BlockMode::kFixed, 0.0};
  // How far the vehicle's mean attitude over a log may lean from level (road crown and
  // grades, a parking spot): the standard deviation, per axis, with which gravity's up axis
  // measures the mount's roll and pitch when T_I_V's rotation is estimated without the LiDAR
  // (docs/calibration.md, Eq. C4), within [0.01, 30] deg; empty ("none" in the file): the
  // mount's prior is the nominal's alone.
  std::optional<double> ground_tilt_sigma_deg = 1.0;
  // Planar-rotation rows (Eq. F27, estimation/planar_rotation_rows.h): the vehicle turns about
  // its own up axis, and the 1-sigma of its roll and pitch rates in rad/s, within [1e-4, 10];
  // 0 ("measured" in the file): measured from the log (Eq. K15); empty ("none", the default):
  // no such rows. For rigid platforms: a car's body pitches with its yaw rate when it brakes
  // into a turn.
  std::optional<double> roll_pitch_rate_sigma_rad_s;
};

// `calibration` with every block fixed (no prior): a solve then estimates the trajectory alone,
// at the nominal calibration.
ProblemCalibration WithEveryBlockFixed(ProblemCalibration calibration);

struct ProblemSolver {
  int max_iterations = 15;   // Ceres iterations per solve, >= 1
  int outer_iterations = 8;  // associate planes -> solve rounds of the batch solver, >= 1
  int num_threads = 1;       // Ceres threads, >= 1
};

// LiDAR point-to-plane residuals.
struct ProblemLidar {
  int max_points_per_sweep = 400;  // residuals per sweep at most, >= 1
  double voxel_m = 0.6;            // one residual point per voxel of this size, [0.01, 20]
  // Every sweep_stride-th sweep becomes a keyframe of the batch solve, >= 1; only these
  // sweeps are read, and the initializer's odometry registers them alone (consecutive sweeps
  // 0.1 s apart see nearly the same scene; docs/calibration.md). What counts keyframes scales
  // with it: the batch's partner sweeps span stride times the time, and wheel and GNSS
  // factors, attached at keyframes, use 1 / stride of the samples.
  int sweep_stride = 1;
};

// Limits that follow from the log's measured rates (sensors/sample_timing.h, Eqs. T1-T3):
// an empty one is derived from the dataset's stamps, a given one overrides that. The gaps lie
// within [0.001, 60] s, keyframe_period_s within [0.005, 10] s, gnss_track_half_width_s within
// [0.1, 60] s.
struct ProblemTiming {
  std::optional<double> max_imu_gap_s;    // bracketing IMU samples of a wheel factor (T1)
  std::optional<double> max_wheel_gap_s;  // bracketing wheel samples (T1); wheel only
  std::optional<double> max_fix_gap_s;    // bracketing GNSS fixes (T1); GNSS only
  // Keyframe spacing of a calibration without the LiDAR (T2); LiDAR off only.
  std::optional<double> keyframe_period_s;
  // Fixes within this of a keyframe are fitted for its track (T3, Eq. K7); GNSS only.
  std::optional<double> gnss_track_half_width_s;
  // A sensor the problem uses must give factors at no fewer than this fraction of the
  // keyframes, else the calibration is an error naming it (a result built on a handful of
  // its samples would be presented as if it used the log), within [0, 1].
  double min_factor_fraction = 0.5;
};

struct Problem {
  // The file the problem was read from, for messages; empty for a problem built in code.
  std::string path;
  std::string description;
  ProblemSensors sensors;
  ProblemCalibration calibration;
  // Robust loss per factor type; defaults in factors/loss.h (wheel huber:2, GNSS cauchy:3,
  // LiDAR huber:1, IMU and priors quadratic).
  factors::FactorLossOptions loss;
  int window_size = 10;  // keyframes of the sliding window, >= 2
  // The sliding window's residual points no farther than this, >= 0 (0: no limit; the batch
  // solve takes every range). Beyond about 40 m the default 32-beam LiDAR's rings lie too far
  // apart for a local plane (docs/sliding_window.md, "Far points"); a denser LiDAR may take
  // more. LiDAR only.
  double window_max_range_m = 40.0;
  ProblemSolver solver;
  ProblemLidar lidar;
  ProblemTiming timing;
};

// Reads and checks a problem file. Throws ParseError (file, line, column) on malformed
// content and autocal::Error when the file cannot be read.
Problem ReadProblemYaml(const std::string& path);

// Refuses a problem that asks for data the dataset does not have: the LiDAR without sweeps in
// lidar.csv, the wheel encoders without the file of the dataset's wheel form (wheel.csv,
// wheel_speed.csv or odometry.csv) or with wheel data in another form than angular rates
// (which the calibration cannot use yet), GNSS without gnss.csv, or an IMU log with
// fewer than two samples; and a sensor none of whose stamps falls inside the IMU's time span
// (the LiDAR's within 1 s of it: its clock is offset), which could add no factor. Throws one
// autocal::Error naming the problem, the dataset and every missing piece, e.g. "problem
// problems/urban_full.yaml estimates wheel_radius_left_m but dataset DIR has no wheel.csv",
// "problem P uses the wheel encoders but 0 of 3950 samples of DIR/wheel.csv fall inside the
// IMU's time span (imu.csv A to B ns, wheel.csv C to D ns: the stamps look like microseconds,
// autocal expects nanoseconds)".
void ValidateProblemForDataset(const Problem& problem, const Dataset& dataset);

}  // namespace io
}  // namespace autocal
