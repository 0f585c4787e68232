#pragma once

// Online estimation of a recorded dataset (docs/sliding_window.md, "Streaming a dataset"):
// the dataset's IMU, wheel, GNSS and LiDAR data are streamed in arrival order through the
// sliding-window estimator, as a car would deliver them. This is what autocal_estimate runs.
//
// The initial state comes from the LiDAR-IMU initializer (estimation::InitializeLidarImu) on
// the first `initialization_duration_s` of the log: its first keyframe starts the window,
// refined by the GNSS-inertial solve over those seconds when GNSS takes part. The initial
// calibration is the dataset's nominal one; the blocks the initializer estimates (q_I_L, p_I_L,
// time offset) take its values when the problem estimates them. With GNSS, a drive the
// initializer cannot use (no turns, or a LiDAR odometry that does not fit the fixes: a
// highway) starts from the offline calibration of those seconds instead (CalibrateDataset),
// whose values also centre the window's priors.
//
// Without the LiDAR (IMU, GNSS and optionally wheels; docs/sliding_window.md, "Without the
// LiDAR") the window's keyframes come at a fixed period (SlidingWindowEstimator::
// AddKeyframeAt): by default the median interval of the GNSS fixes, clamped to [0.05, 0.5] s,
// so that each keyframe interval holds about one fix. The initial state is the first of the
// GNSS-inertial keyframes (estimation::KeyframesFromGnssAndImu) over the first
// `initialization_duration_s`, the calibration the nominal one. The outputs are the same.

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "autocal/estimation/calibration_initializer.h"
#include "autocal/estimation/sliding_window.h"
#include "autocal/io/calibration_yaml.h"
#include "autocal/io/dataset.h"
#include "autocal/io/problem_yaml.h"

namespace autocal {
namespace pipeline {

struct OnlineEstimationProgress {
  double log_fraction = 0.0;         // of the log's duration streamed so far, 0 ... 1
  int64_t updates = 0;               // window updates (keyframes) so far
  double update_s = 0.0;             // wall time of the last update
  sensors::Calibration calibration;  // current estimate
};

struct OnlineEstimationOptions {
  // Seconds of the log (from its first sweep; without the LiDAR from the first moment the IMU
  // and GNSS share) given to the initializer. The window starts at the first keyframe the
  // initializer returns.
  double initialization_duration_s = 30.0;
  // Without the LiDAR: the keyframe period; 0 derives it from the GNSS rate (above).
  double keyframe_period_without_lidar_s = 0.0;
  // Every n-th sweep of those seconds goes to the initializer (docs/sliding_window.md,
  // "Streaming a dataset"): its odometry then registers sweeps 0.3 s apart, which costs less
  // and gives the time offset larger rotations to correlate (docs/history/sliding_window.md).
  int initializer_sweep_stride = 3;
  // With GNSS, the most the initializer's LiDAR odometry may miss the fixes by (RMS, after the
  // 4-DoF alignment) for its extrinsic's yaw to be kept; beyond it, or when its track is too
  // short to give the yaw (a highway), the window's calibration starts from the offline
  // calibration of the initialization seconds, whose values also centre the window's priors
  // (OfflineCalibrationOptions::max_odometry_to_gnss_rms_m, docs/sliding_window.md).
  double max_odometry_to_gnss_rms_m = 20.0;
  // The window refines the initializer's extrinsic and offset, so the faster settings serve,
  // as in the offline calibration (docs/sliding_window.md, "Streaming a dataset").
  estimation::CalibrationInitializerOptions initializer =
      estimation::RefinedLaterInitializerOptions();
  // Window settings that the problem file does not set (noise, association, keyframes...).
  // window_size, solver iterations and threads, losses, residual points and the estimated
  // blocks come from the problem; IMU and wheel noise from the dataset. Smoothing is on: the
  // result holds the smoothed trajectory beside the filtered one.
  estimation::SlidingWindowOptions window = [] {
    estimation::SlidingWindowOptions w;
    w.smoothing = true;
    return w;
  }();
  // 1-sigma of the prior on the initial state: the initializer's first keyframe is good to a
  // few centimetres and tenths of a degree, not to the window's defaults (meant for a known
  // start). With GNSS they add to the GNSS-inertial start's own covariance.
  estimation::SlidingWindowInitialStateSigmas initial_state_sigmas = [] {
    estimation::SlidingWindowInitialStateSigmas s;
    s.rotation_deg = 0.5;
    s.position_m = 0.1;
    s.velocity_m_s = 0.1;
    return s;
  }();
  // With GNSS, 1-sigma of the initial position instead of initial_state_sigmas.position_m:
  // the aligned initializer keyframe can be off by a metre in height (a drift of the
  // initializer's trajectory spread by the alignment), and held tighter the GNSS lever arm
  // absorbed that offset; the fixes fix the position instead.
  double initial_position_sigma_with_gnss_m = 2.0;
  // With GNSS, 1-sigma of the initial accelerometer bias instead of initial_state_sigmas': the
  // start then comes from the GNSS-inertial solve over the initialization span, whose turns
  // tell the bias from the tilt. Until the window's own drive turns, roll and the lateral bias
  // trade against each other, so a wider sigma lets the roll wander.
  double initial_accel_bias_sigma_with_gnss_m_s2 = 0.02;
  // Test the blocks the problem fixes against the whole stream at its end, as the offline
  // calibration does (a warning per direction the data would move by more than
  // OfflineCalibrationOptions::max_fixed_block_step_sigmas sigmas; docs/sliding_window.md,
  // "Fixed blocks"). The window then marginalizes each keyframe a second time with those
  // blocks free; the estimate is the same either way.
  bool test_fixed_blocks = true;
  // The stream cut into scatter_stretches equal spans, the estimate's steps between their ends
  // (scatter_stretches - 1 steps) against its covariance (docs/sliding_window.md, Eq. W9):
  // where their median square exceeds chance's at scatter_significance, the final sigmas are
  // widened by the steps' scatter. The covariance is computed at each span's end. 0: no
  // test; else at least 3 (two steps).
  int scatter_stretches = 32;
  double scatter_significance = 0.001;
  // Called after every window update; may be empty.
  std::function<void(const OnlineEstimationProgress&)> progress;
};

// The calibration estimate after one window update.
struct CalibrationSample {
  int64_t t_ns = 0;  // the new keyframe's time (IMU clock)
  sensors::Calibration calibration;
};

struct OnlineEstimationResult {
  // Final values with sigma from the window's calibration covariance; blocks the problem
  // holds carry no sigma. solver: counters of the run; residuals["lidar"]: the last update's.
  io::CalibrationFile calibration;
  io::Trajectory trajectory;  // every keyframe, marginalized ones as last estimated
  // The same keyframes smoothed from the final window (SlidingWindowEstimator::
  // SmoothedTrajectory); empty when window.smoothing is off.
  io::Trajectory smoothed_trajectory;
  // The same keyframes' full states: pose, velocity and the IMU biases.
  std::vector<estimation::SlidingWindowState> states;
  std::vector<CalibrationSample> calibration_over_time;
  estimation::SlidingWindowCounters counters;
  // The calibration the window started from: the initializer's, or the offline calibration
  // of the first seconds where the initializer could not start it.
  sensors::Calibration initial;
  // Plain-language findings of the start: the clock offsets the window holds, a nominal mount
  // replaced by the data's, the initializer's fallbacks to nominal values, a start from the
  // offline calibration of the first seconds.
  std::vector<std::string> warnings;
  double keyframe_period_s = 0.0;  // without the LiDAR; 0 with it (keyframes are sweeps)
  double seconds_total = 0.0;
  // Of seconds_total: loading its sweeps, the initializer, the start's solves.
  double seconds_initialization = 0.0;
};

// Streams the dataset through the window. Throws autocal::Error naming what is wrong when the
// problem asks for data the dataset lacks, asks for what the window does not estimate
// (one shared wheel radius, only one radius estimated), has neither the LiDAR nor GNSS, or
// when the initializer cannot start (its reasons; with GNSS, those of the offline calibration
// of the first seconds that stands in for it; without the LiDAR: too few fixes, or too short
// an overlap of IMU and GNSS for two keyframes). A file error keeps its autocal::ParseError.
OnlineEstimationResult EstimateDatasetOnline(const io::Dataset& dataset, const io::Problem& problem,
                                             const OnlineEstimationOptions& options = {});

// Writes trajectory.tum, trajectory_smoothed.tum (when smoothed), states.csv,
// calibration_over_time.csv and calibration.yaml into `directory` (created).
// calibration_over_time.csv columns: t_s (IMU clock, seconds), then every block of the
// calibration table in sensors::CalibrationBlocks() order, by name (quaternions qx qy qz qw,
// docs/sliding_window.md). states.csv columns: t_s, p_W_I (m), q_W_I (qx qy qz qw), v_W_I (m/s),
// b_g (rad/s), b_a (m/s^2). Throws autocal::Error on I/O failure.
void WriteOnlineEstimationResult(const std::string& directory,
                                 const OnlineEstimationResult& result);

}  // namespace pipeline
}  // namespace autocal
