#pragma once

// The steps both offline calibration paths share (docs/calibration.md): the wheel and GNSS
// factors on the keyframes and the conclusion (observability,
// uncertainty, the result's calibration, trajectory and timings); and the path without the
// LiDAR, which CalibrateDataset dispatches to.

#include <ceres/ceres.h>

#include <chrono>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "autocal/estimation/calibration_initializer.h"
#include "autocal/estimation/calibration_observability.h"
#include "autocal/estimation/gnss_inertial_keyframes.h"
#include "autocal/estimation/gnss_noise.h"
#include "autocal/estimation/lidar_inertial_batch.h"
#include "autocal/estimation/planar_rotation_rows.h"
#include "autocal/estimation/sliding_window.h"
#include "autocal/factors/wheel_factor.h"
#include "autocal/geometry/manifolds.h"
#include "autocal/io/dataset.h"
#include "autocal/io/problem_yaml.h"
#include "autocal/pipeline/offline_calibration.h"
#include "autocal/sensors/calibration.h"
#include "autocal/sensors/gnss_enu.h"
#include "autocal/sensors/sample_timing.h"

namespace autocal {
namespace pipeline {

// Passes one stage's progress to options.progress, when there is one.
void Report(const OfflineCalibrationOptions& options, const std::string& stage, double fraction,
            double cost, double seconds_left);

// A block in estimate or prior mode is estimated; a fixed one is held at its initial guess.
bool Estimated(io::BlockMode mode);

// `nominal` with the initializer's LiDAR blocks (rotation, translation, time offset) for those
// the problem estimates.
sensors::Calibration StartFromInitializer(const sensors::Calibration& nominal,
                                          const io::ProblemCalibration& blocks,
                                          const estimation::CalibrationInitialization& init);

// The parts with `separator` between them.
std::string Join(const std::vector<std::string>& parts, const std::string& separator);

// The limits that follow from the log's rates (sensors/sample_timing.h, Eqs. T1-T3), each
// replaced by the problem's timing: setting where the file gives one.
struct TimingLimits {
  sensors::SampleTiming imu;
  std::optional<sensors::SampleTiming> wheel;  // when the problem uses the wheels
  std::optional<sensors::SampleTiming> gnss;   // when the problem uses GNSS
  double max_imu_gap_s = 0.0;
  double max_wheel_gap_s = 0.0;
  double max_fix_gap_s = 0.0;
  double keyframe_period_s = 0.0;  // without the LiDAR
  double gnss_track_half_width_s = 0.0;
  double min_factor_fraction = 0.0;
};

// The dataset's timing for the sensors the problem uses (use_wheel, use_gnss), with the
// problem's overrides. Throws autocal::Error naming the file whose stamps are too few or out
// of order.
TimingLimits DeriveTimingLimits(const io::Dataset& dataset, const io::Problem& problem,
                                bool use_wheel, bool use_gnss);

// The measured rates and the limits used, into the result's solver summary (calibration.yaml):
// timing_<sensor>_rate_hz and timing_<limit> (keyframe_period_s only without the LiDAR).
void RecordTiming(const TimingLimits& timing, bool without_lidar, io::CalibrationFile* file);

// The GNSS-inertial keyframes (estimation::KeyframesFromGnssAndImu) as every start runs them:
// the dataset's IMU noise and gravity, the gaps and track window of `timing`, the wheel form's
// row sigmas (WheelNoise) and the problem's threads.
estimation::GnssInertialKeyframesOptions GnssInertialStart(const io::Dataset& dataset,
                                                           const io::Problem& problem,
                                                           const TimingLimits& timing);

// The wheel samples of the form the dataset holds, when the problem uses the wheels (else none).
estimation::WheelData StartWheelData(const io::Dataset& dataset, bool use_wheel);

// Keyframes every period_ns over [first_ns, last_ns], leaving out each one with no IMU sample
// since the keyframe before it (sensors::ImuSampleBetween: an IMU dropout, whose IMU factor
// could not be formed); the next keyframe's factor spans the dropout. With any left out, a
// warning (ImuDropoutWarning for "the keyframes") goes to *warnings.
std::vector<estimation::Keyframe> KeyframesEvery(const sensors::ImuSamples& imu, int64_t first_ns,
                                                 int64_t last_ns, int64_t period_ns,
                                                 std::vector<std::string>* warnings);

// The warning for `skipped` keyframes of `where` ("the keyframes", "the window") left out in IMU
// dropouts, with the log's longest IMU interval; empty for none.
std::string ImuDropoutWarning(const sensors::ImuSamples& imu, int64_t skipped,
                              const std::string& where);

// The sigmas of the form's factor rows from sensors.yaml's wheel noise, and the rear axle's
// lateral slip with its cornering compliance (Eq. K6c); a sensors.yaml without a wheel:
// section, or no sensors.yaml, means the defaults of sensors/sensor_config.h
// (datasets/README.md). The other fields of *wheel are kept.
void SetWheelNoise(const io::Dataset& dataset, const sensors::Calibration& nominal,
                   estimation::KeyframeWheelOptions* wheel);

// b_ctrl of the odometry twist: sensors.yaml's wheel.controller_track_m, else the nominal
// effective track.
double ControllerTrackM(const io::Dataset& dataset, const sensors::Calibration& nominal);

// The wheel and GNSS factors of the problem on the keyframes (docs/keyframe_factors.md), and
// the priors of the estimated blocks. A sensor that gives factors at fewer than
// timing->min_factor_fraction of the keyframes is an autocal::Error naming it, its rate, the
// count and the limit: no result silently leaves most of a sensor out.
struct SensorFactors {
  const io::Dataset* dataset = nullptr;
  const io::Problem* problem = nullptr;
  const sensors::Calibration* nominal = nullptr;
  bool use_wheel = false;
  bool use_gnss = false;
  const sensors::EnuConverter* enu = nullptr;
  const std::vector<estimation::EstimatedBlock>* blocks = nullptr;
  geometry::RightQuaternionManifold* quaternion_manifold = nullptr;
  const TimingLimits* timing = nullptr;
  // Every wheel row's sigma times this: the data's noise when it exceeds the stated one
  // (pipeline/clock_initialization.h, WheelNoiseScale).
  double wheel_noise_scale = 1.0;
  // The GNSS rows' sigma scaled per axis group: the fixes' scatter when it exceeds their
  // stated std (MeasureGnssNoise).
  estimation::GnssStdScale gnss_noise_scale = {};
  // When set, receives what the planar-rotation rows (Eq. F27) measured and used.
  estimation::PlanarRotationRows* planar_rotation = nullptr;

  void Add(ceres::Problem* p, std::vector<estimation::Keyframe>* keyframes,
           sensors::Calibration* c) const;
  // The GNSS factors' settings from the problem, the timing and gnss_noise_scale.
  estimation::KeyframeGnssOptions GnssOptions() const;
  // Whether a wheel or GNSS clock the problem estimates gives the keyframes other samples
  // (docs/keyframe_factors.md, Eq. K17) at its value in `to` than at its value in `from`:
  // factors added at `from` would then no longer pair each keyframe with its nearest sample.
  bool PairingChanges(const std::vector<estimation::Keyframe>& keyframes,
                      const sensors::Calibration& from, const sensors::Calibration& to) const;
};

// Eq. N2 (estimation/gnss_noise.h) about a solved trajectory (`keyframes`, `c`): the GNSS
// rows of `factors`, whitened by the fixes' stated std. Nothing without GNSS rows. Throws
// autocal::Error when a row cannot be evaluated there.
estimation::GnssNoiseFromResiduals MeasureGnssNoise(const SensorFactors& factors,
                                                    std::vector<estimation::Keyframe>* keyframes,
                                                    sensors::Calibration* c);

// What a GNSS scatter beyond the stated std may mean, ending every Eq. N2 warning.
inline constexpr const char* kGnssScatterCauses =
    "The receiver's std leaves errors out, or the model misses something the fixes see (a "
    "lever arm or a clock held wrong)";

// The warning that says which GNSS rows scatter beyond their stated std, with the figures,
// where (`about`: "about the solved trajectory") and what was done (`applied`: "each is scaled
// by that"); empty when none do.
std::string GnssNoiseWarning(const estimation::GnssNoiseFromResiduals& noise,
                             const std::string& about = "about the solved trajectory",
                             const std::string& applied = "each is scaled by that");

// residuals.gnss.noise_scale_horizontal and noise_scale_vertical of `file`.
void RecordGnssNoiseScale(const estimation::GnssStdScale& scale, io::CalibrationFile* file);

// The GNSS rows of `residuals` ("gnss") before the solve, whitened by the stated std, divided
// by `scale` as the rows after it are (AddGnssFactors' blocks: two horizontal rows, then one
// vertical, per keyframe).
void WhitenGnssRowsBeforeAlike(const estimation::GnssStdScale& scale,
                               std::map<std::string, SensorResiduals>* residuals);

// The planar-rotation rows' count and sigmas (and, when measured, the spread and correlation
// scale behind them, Eq. K15) into the solver summary: planar_rotation_rows,
// planar_rotation_sigma_rad_s, planar_rotation_spread_rad_s, planar_rotation_correlation_scale.
// Nothing without rows.
void RecordPlanarRotation(const estimation::PlanarRotationRows& rows, io::CalibrationFile* file);

// Before the online estimator streams the log: throws one autocal::Error naming the file when
// the wheels or GNSS (use_wheel, use_gnss) have no sample after the initial state at t0_ns
// (the initialization used up their whole log), since the window would then get none.
void RequireSamplesAfter(const io::Dataset& dataset, bool use_wheel, bool use_gnss, int64_t t0_ns);

// The online estimator's counterpart of the offline solve's factor check: throws one
// autocal::Error naming the sensor when the wheels or GNSS (use_wheel, use_gnss) had no
// sample accepted by the sliding window (all before the initial state, late or out of order),
// so that no result is presented that silently left them out.
void RequireStreamedSamples(const io::Dataset& dataset, bool use_wheel, bool use_gnss,
                            const estimation::SlidingWindowCounters& counters);

// Throws the no-factor error when the LiDAR is in the problem and no point was associated.
void RequireLidarFactors(const io::Dataset& dataset, const io::Problem& problem,
                         size_t num_keyframes, const OfflineCalibrationResult& result);

// The iterations a solve took: Ceres' list of them starts with the evaluation at its start.
int SolverIterations(const ceres::Solver::Summary& summary);

// The options of the joint solves: sparse normal Cholesky on the problem's threads, at most
// `max_iterations` iterations.
ceres::Solver::Options JointSolverOptions(const io::Problem& problem, int max_iterations);

// Eq. C3: when Observe held directions, pins them in `p` (the solved problem, whose blocks
// are the keyframes and `calibration`) and solves it again from `solved` (the calibration
// before Observe) with the held directions at their prior, so that the trajectory, the
// residuals and the other blocks follow the calibration that is reported, then removes the
// pins (the held values are known only to their priors' sigma, Eq. C7). Throws
// autocal::Error when that solve fails; warns when it stops at its iteration limit
// (max_iterations, 0: the problem's solver.max_iterations).
void SolveAgainAfterHolding(const io::Problem& problem,
                            const std::vector<estimation::EstimatedBlock>& blocks_estimated,
                            const estimation::BlockObservability& observability,
                            const sensors::Calibration& solved, sensors::Calibration* calibration,
                            ceres::Problem* p, OfflineCalibrationResult* result,
                            int max_iterations = 0);

// Throws one autocal::Error naming every direction the data inform that lies more than
// options.max_prior_deviation_sigmas prior sigmas from its prior (ImplausibleDirections):
// before the observability is judged, and again after SolveAgainAfterHolding, whose solve may
// move the kept directions once the held ones are pinned.
void RequirePlausible(const io::Dataset& dataset, const OfflineCalibrationOptions& options,
                      const std::vector<estimation::EstimatedBlock>& blocks_estimated,
                      const estimation::BlockCovariance& covariance);

// Eq. C7: one warning for each direction of a block the problem holds fixed that the data at
// the solution of `p` would move by more than options.max_fixed_block_step_sigmas sigmas
// (estimation::FixedDirectionsTheDataMove, its sigma as PosteriorCovariance's widened as
// WidenedForScatter's, at the step's residuals): the move, then options.fixed_block_advice (the
// online estimator words its warnings the same).
void WarnOfFixedDirectionsTheDataMove(const io::Problem& problem, const io::SensorsConfig& sensors,
                                      const OfflineCalibrationOptions& options, bool use_wheel,
                                      bool use_gnss, sensors::Calibration* calibration,
                                      ceres::Problem* p, std::vector<std::string>* warnings);

// The residual blocks of `problem` whose Hessian the covariance completes (Eq. C5): all but
// the LiDAR's point groups and the planar-rotation rows (PosteriorCovariance).
std::vector<ceres::ResidualBlockId> ExactResidualBlocks(const ceres::Problem& problem);

// The covariance of the estimated blocks at the solution of `problem`, each residual block with
// its exact Hessian, J^T J + rho' sum r d2r (Eq. C5), but two kinds: the LiDAR's point groups
// (their loss is inside the factor, their Jacobian is the points' geometry) and the
// planar-rotation rows (they leave out the one column whose derivative is noise, Eq. F27b).
// Where the completed matrix is not positive definite (a solve stopped off a minimum), J^T J
// alone, with a warning. `lidar` scales the point groups' information (LidarSandwich).
// `ordering` keeps the fill-reducing ordering for the bound at the truth on the same problem.
estimation::BlockCovariance PosteriorCovariance(
    const std::vector<estimation::EstimatedBlock>& blocks_estimated, ceres::Problem* problem,
    int num_threads, std::vector<std::string>* warnings,
    const estimation::ScaledInformation& lidar = {},
    estimation::CovarianceOrdering* ordering = nullptr);

// The residual sources of `problem` (ResidualSources) but the priors: the sensors whose rows'
// scatter Eq. C8 judges.
std::vector<estimation::ResidualSource> SensorSources(ceres::Problem* problem);

// Throws autocal::Error unless options.scatter_stretches is 0 or at least 2 and
// options.scatter_significance lies in (0, 1).
void CheckScatterOptions(const OfflineCalibrationOptions& options);

// Eq. C8: `covariance` (PosteriorCovariance's at the solution of `problem`) widened where a
// sensor's rows scatter over options.scatter_stretches stretches of the log beyond their noise
// model (estimation::WidenedForScatter). Each sensor judged gets its largest ratio in the
// result's residuals (`stretch_scatter_ratio`, over the directions it informs), and each that
// widens a sigma a warning naming the direction it widens most.
estimation::BlockCovariance WidenedForScatter(
    const std::vector<estimation::EstimatedBlock>& blocks_estimated, ceres::Problem* problem,
    const estimation::BlockCovariance& covariance, const OfflineCalibrationOptions& options,
    int num_threads, estimation::CovarianceOrdering* ordering, OfflineCalibrationResult* result);

// The LiDAR point groups of `problem` with their information scale 1 / kappa, kappa the robust
// loss's sandwich ratio over their whitened distances at the problem's values (Eq. C6): the
// points' loss makes J^T J with the rows' Gauss-Newton weights misstate the M-estimator's
// variance. Scale 1 without point groups or without a loss.
estimation::ScaledInformation LidarSandwich(ceres::Problem* problem);

// result->posterior from the solve's calibration (`solved`), the blocks' priors and their
// covariance as solved and widened (Eq. C8), before Observe holds any direction.
void RecordPosterior(const std::vector<estimation::EstimatedBlock>& blocks_estimated,
                     const estimation::BlockCovariance& covariance,
                     const estimation::BlockCovariance& widened, const sensors::Calibration& solved,
                     OfflineCalibrationResult* result);

// With options.set_to_truth: result->bound, the covariance of the estimated blocks from
// `problem` at the truth (the Cramer-Rao bound), and result->error_budget, the error split by
// the sources of the residuals (ResidualSources). The keyframes and the
// calibration, the problem's blocks, are set to the truth for it and restored after. A bound
// that cannot be computed (a singular information matrix) is a warning. The bound takes the
// posterior's LiDAR information scale (`lidar`); the budget splits the solver's own J^T J.
void RecordBoundAtTruth(const OfflineCalibrationOptions& options,
                        const std::vector<estimation::EstimatedBlock>& blocks_estimated,
                        std::vector<estimation::Keyframe>* keyframes,
                        sensors::Calibration* calibration, ceres::Problem* problem, int num_threads,
                        OfflineCalibrationResult* result,
                        const estimation::ScaledInformation& lidar = {},
                        estimation::CovarianceOrdering* ordering = nullptr);

// Observability and uncertainty (step 4): directions the drive did not excite are held at
// their prior value, the rest conditioned on them (Eq. C1-C2), in `calibration` (the blocks'
// data point into it), by `covariance` (widened by Eq. C8); sigma, flags and warnings go into
// the result. Returns the flags (empty without a covariance). Throws when the solve ended
// implausibly far from the priors, judged by `solved`, the covariance of the weighting that
// moved the estimate there (RequirePlausible).
estimation::BlockObservability Observe(
    const io::Dataset& dataset, const OfflineCalibrationOptions& options,
    const std::vector<estimation::EstimatedBlock>& blocks_estimated,
    const estimation::BlockCovariance& solved, const estimation::BlockCovariance& covariance,
    OfflineCalibrationResult* result);

// With the problem's wheel_radius_shared, one block stands for both rear wheels: the right
// radius in `file` takes the left's value, sigma and flag (not a value without a sigma, which
// reads as a fixed block). Nothing otherwise.
void GiveBothWheelsTheSharedRadius(const io::Problem& problem, io::CalibrationFile* file);

// The result's calibration values, trajectory, residual statistics and timings, from
// `keyframes` and `calibration` as they are (after SolveAgainAfterHolding, so that both come
// from one solve).
void Conclude(const io::Dataset& dataset, const io::Problem& problem,
              const std::vector<estimation::Keyframe>& keyframes, sensors::Calibration* calibration,
              std::chrono::steady_clock::time_point start, OfflineCalibrationResult* result);

// Without the LiDAR (docs/calibration.md, "Without the LiDAR"): keyframes every
// inertial_keyframe_period_s are placed on the GNSS track and refined with the IMU and the
// wheels (estimation/gnss_inertial_keyframes.h), then one least-squares problem of IMU,
// wheel and GNSS factors and the blocks' priors estimates the wheel blocks, T_I_V and the
// lever arm with the keyframe states. `start` is when CalibrateDataset began.
OfflineCalibrationResult CalibrateWithoutLidar(const io::Dataset& dataset,
                                               const io::Problem& problem,
                                               const OfflineCalibrationOptions& options,
                                               std::chrono::steady_clock::time_point start);

}  // namespace pipeline
}  // namespace autocal
