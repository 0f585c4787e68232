#pragma once

// Offline calibration of a recorded dataset (docs/calibration.md): load and validate →
// initialize without a hand-measured guess → batch solve over the whole log → covariance and
// observability → a result in the calibration.yaml schema, the trajectory, and a report.
// This is what autocal_calibrate runs; estimators linking the library may call it directly.

#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "autocal/estimation/calibration_fusion.h"
#include "autocal/estimation/calibration_initializer.h"
#include "autocal/estimation/clock_offsets.h"
#include "autocal/estimation/keyframe.h"
#include "autocal/estimation/lidar_inertial_batch.h"
#include "autocal/io/calibration_yaml.h"
#include "autocal/io/dataset.h"
#include "autocal/io/problem_yaml.h"
#include "autocal/io/run_status.h"

namespace autocal {
namespace pipeline {

struct CalibrationProgress {
  std::string stage;          // "loading sweeps", "initializing", "solving"
  double fraction = 0.0;      // of the stage, 0 ... 1
  double cost = 0.0;          // solver cost, when solving
  double seconds_left = 0.0;  // estimate for the stage, 0 when unknown
};

struct OfflineCalibrationOptions {
  // Initializer settings; its IMU noise and the lever-arm prior are taken from the dataset.
  // The batch refines the initializer's rotation and offset (from a few degrees and
  // milliseconds off), so the faster settings serve.
  estimation::CalibrationInitializerOptions initializer =
      estimation::RefinedLaterInitializerOptions();
  // The LiDAR odometry's keyframes are aligned to GNSS (yaw and shift); when they miss the
  // fixes by more than this RMS afterwards (or span too little to give the yaw), the odometry
  // did not follow the drive and the keyframes are rebuilt from GNSS and the IMU instead
  // (docs/calibration.md). A working track misses by metres (its drift and the initializer's
  // scale), which the batch corrects; a failed one by hundreds of metres.
  double max_odometry_to_gnss_rms_m = 20.0;
  // Without the LiDAR, a keyframe every this many seconds (docs/calibration.md, "Without the
  // LiDAR"). Empty: the problem's timing.keyframe_period_s, else derived from the log's rates
  // (sensors/sample_timing.h, Eq. T2: 0.1 s for 10 Hz GNSS, 0.5 s for 1 Hz).
  std::optional<double> inertial_keyframe_period_s;
  // Every estimated block carries a prior at the nominal value: the problem's sigma in prior
  // mode, else the dataset's nominal uncertainty, else these weak defaults, which keep the
  // problem regular where the drive excites nothing (an excited direction ends far inside).
  double default_translation_prior_sigma_m = 0.3;  // T_I_L, T_I_V, p_I_A
  double default_rotation_prior_sigma_deg = 5.0;   // T_I_L, T_I_V
  double default_time_offset_prior_sigma_s = 0.05;
  double default_wheel_radius_prior_sigma_m = 0.01;
  double default_track_width_prior_sigma_m = 0.05;
  // A direction whose sigma exceeds its limit is reported unobservable: held at its nominal
  // value when the drive left it at its prior (below), else kept at its estimate; the others
  // are conditioned on the held ones (docs/calibration.md, Eq. C1-C2). The LiDAR, offset, radius
  // and lever-arm limits are the accuracy a calibration is expected to reach (0.1 deg, 1 cm, 0.5
  // ms, 0.1 % of a radius, 2 cm): a direction known less well is not reported as found.
  double max_observable_rotation_sigma_deg = 0.1;          // T_I_L
  double max_observable_vehicle_rotation_sigma_deg = 0.3;  // T_I_V (only scales wheel speeds)
  double max_observable_translation_sigma_m = 0.01;        // T_I_L
  double max_observable_time_offset_sigma_s = 0.0005;
  double max_observable_wheel_radius_sigma_m = 0.0003;
  double max_observable_track_width_sigma_m = 0.005;
  double max_observable_vehicle_translation_sigma_m = 0.05;  // T_I_V
  double max_observable_lever_arm_sigma_m = 0.02;            // p_I_A
  // A direction is held at its nominal value (Eq. C1-C2) when the drive left it near its
  // prior: its posterior sigma above this fraction of the prior sigma (at 0.5: the drive added
  // less than 3 times the prior's information) ...
  double max_posterior_to_prior_sigma = 0.5;
  // ... or above this multiple of its observability limit above. Weakly determined directions
  // are where unmodelled effects show, and a weak prior (the defaults, when the dataset states
  // no nominal uncertainty) does not hold them (docs/history/calibration.md).
  double max_kept_sigma_to_limit = 4.0;
  // A solve that moves any direction farther than this many prior sigmas from the nominal
  // value is not trusted: CalibrateDataset throws instead of returning it.
  double max_prior_deviation_sigmas = 5.0;
  // A block the problem fixes is named in a warning when the data would move a direction they
  // inform by more than this many sigmas of that step (Eq. C7, docs/calibration.md).
  double max_fixed_block_step_sigmas = 5.0;
  // What such a warning advises, after the move: a block the problem file fixes by default; a
  // run that fixes the blocks itself says what the move means there.
  std::string fixed_block_advice =
      ": the fixed value disagrees with the drive; estimate the block (or give it a prior) in the "
      "problem file, or correct its nominal value";
  // Each sensor's rows are cut into this many stretches of the log, and the calibration's
  // sigmas widened where a sensor's stretches scatter beyond its noise model at this
  // significance per direction (Eq. C8, docs/calibration.md); 0 stretches: not tested.
  int scatter_stretches = 16;
  double scatter_significance = 0.001;
  // Called as the stages advance; may be empty.
  std::function<void(const CalibrationProgress&)> progress;
  // When set, sets the keyframes and the calibration to the truth (a simulated log:
  // evaluation::TruthSetter), and the final problem's covariance is computed there as well:
  // the Cramer-Rao bound of the estimated blocks, in OfflineCalibrationResult::bound.
  estimation::StateSetter set_to_truth;
};

// Whitened residuals of one sensor's factors (each row over its sigma, before any robust
// loss) at the start of the solve and after it.
struct SensorResiduals {
  std::vector<double> before;
  std::vector<double> after;
  // After the solve: the sensor's factors (residual blocks), those its robust loss
  // down-weighted (a weight rho'(s) below one half at the block's squared whitened norm s),
  // and the RMS of the rows of the others.
  size_t factors = 0;
  size_t factors_downweighted = 0;
  double rms_not_downweighted = 0.0;
};

struct OfflineCalibrationResult {
  // Values, sigma per component, observability, solver summary, residual statistics.
  io::CalibrationFile calibration;
  io::Trajectory trajectory;  // one state per keyframe (IMU clock)
  // The GNSS fixes in W (ENU at the first fix) when GNSS took part, for the report.
  std::vector<Eigen::Vector3d> gnss_positions_W;
  // Plain-language findings: directions the drive did not excite, unreliable steps.
  std::vector<std::string> warnings;
  estimation::CalibrationInitialization initialization;
  // The LiDAR odometry did not follow the drive: the keyframes were rebuilt from GNSS and the
  // IMU, and the LiDAR blocks started from their nominal values, not the initializer's.
  bool lidar_blocks_from_nominal = false;
  // The clocks' cross-correlations that started their offsets (docs/calibration.md), for the
  // report: the wheels' (with the signal compared) and the GNSS receiver's, when estimated.
  std::optional<estimation::WheelImuOffset> wheel_clock_initialization;
  std::optional<estimation::SeriesOffsetEstimate> gnss_clock_initialization;
  estimation::LidarInertialBatchReport batch;
  // What this log says of the estimated blocks before any direction was held (their values,
  // priors and joint covariance): several logs combine from these (multi_log_calibration.h).
  // covariance.ok is false when the covariance could not be computed.
  estimation::CalibrationPosterior posterior;
  // Per sensor that took part besides the LiDAR (whose point-to-plane distances in metres are
  // in `batch`): "imu", "wheel", "gnss".
  std::map<std::string, SensorResiduals> whitened_residuals;
  sensors::Calibration nominal;  // the dataset's initial guess, for comparison
  // The centres of the blocks' priors, where a held direction is held: the nominal, unless the
  // initialization replaced the mount (a nominal no guess) or fused gravity into its roll and
  // pitch (docs/calibration.md, Eq. C4).
  sensors::Calibration prior_centre;
  // With OfflineCalibrationOptions::set_to_truth: the covariance of posterior.blocks from the
  // final problem's information at the truth instead of the estimate (the Cramer-Rao bound,
  // docs/evaluation.md "Information bound"), laid out as posterior.covariance.
  std::optional<estimation::BlockCovariance> bound;
  // With the bound: each direction's error, truth - estimate in the block's tangent at the
  // solve (a rotation: Log(q_estimate^-1 q_truth)), before any direction was held; laid out
  // as the bound's rows.
  Eigen::VectorXd error_at_bound;
  // With the bound: where the error comes from, by source, at the truth (docs/evaluation.md,
  // "Where the error comes from"), laid out as the bound's rows.
  std::optional<estimation::ErrorBudget> error_budget;
  double seconds_total = 0.0;  // wall time, and its stages
  double seconds_loading = 0.0;
  double seconds_initialization = 0.0;
  double seconds_solve = 0.0;  // batch solve, covariance and observability
  // Of the solve: the posterior covariance, the bound at the truth and the observability; and
  // the solve again with the unobservable directions held (0 when none is).
  double seconds_uncertainty = 0.0;
  double seconds_after_holding = 0.0;
};

// Runs the whole calibration; without the LiDAR in the problem, from keyframes on the GNSS
// track, or dead reckoned from the IMU and the wheels without fixes (docs/calibration.md,
// "Without the LiDAR"). Throws autocal::Error with a message naming what is wrong when the
// problem asks for data the dataset lacks, when the drive cannot initialize the calibration
// (the initializer's reasons), when the solve ends implausibly far from the priors
// (max_prior_deviation_sigmas), or when a problem without the LiDAR has neither GNSS nor
// wheels.
OfflineCalibrationResult CalibrateDataset(const io::Dataset& dataset, const io::Problem& problem,
                                          const OfflineCalibrationOptions& options = {});

// Writes calibration.yaml, trajectory.tum (TUM format, seconds),
// calibration_per_iteration.csv, timings.yaml, warnings.txt, report.html and, when `status` is
// given, status.yaml into `directory` (created), all at once: the directory appears whole or
// not at all (io/output_files.h), so a run stopped while writing never leaves a complete
// result without its status. Throws autocal::Error on I/O failure.
void WriteCalibrationResult(const std::string& directory, const OfflineCalibrationResult& result,
                            const io::RunStatus* status = nullptr);

// A plain-text summary table (values, sigma, observability, warnings) for terminals.
std::string FormatCalibrationSummary(const OfflineCalibrationResult& result);

// Its first part: one line per estimated block (value, sigma, observable per direction).
std::string FormatCalibrationValues(const io::CalibrationFile& file);

}  // namespace pipeline
}  // namespace autocal
