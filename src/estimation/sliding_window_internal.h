#pragma once

// The sliding window's implementation (docs/sliding_window.md), private to the library:
// SlidingWindowEstimator forwards to SlidingWindowEstimator::Impl, whose member functions are
// spread over sliding_window.cc (streaming input, one update), sliding_window_keyframes.cc
// (keyframes and their interval factors), sliding_window_problem.cc (the window problem, its
// solve and marginalization) and sliding_window_smoothing.cc.

#include <ceres/ceres.h>

#include <cstdint>
#include <deque>
#include <initializer_list>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "autocal/estimation/marginalization.h"
#include "autocal/estimation/sliding_window.h"
#include "autocal/estimation/sliding_window_blocks.h"
#include "autocal/geometry/manifolds.h"
#include "autocal/lidar/plane_map.h"
#include "autocal/sensors/gnss_enu.h"
#include "autocal/sensors/imu_preintegration.h"
#include "estimation/point_group_pool.h"
#include "estimation/sliding_window_factors.h"
#include "estimation/sweep_pairing.h"
#include "estimation/turning_axis.h"
#include "estimation/window_solver.h"

namespace autocal {
namespace estimation {

class SlidingWindowEstimator::Impl {
 public:
  Impl(const SlidingWindowOptions& options, const sensors::Calibration& initial_calibration,
       const SlidingWindowState& initial_state);

  bool AddImu(const sensors::ImuSample& sample);
  bool AddWheel(const sensors::WheelSample& sample);
  bool AddWheelSpeeds(const sensors::WheelSpeedSample& sample);
  bool AddOdometry(const sensors::OdometrySample& sample);
  // Counts a wheel stamp (either form) not newer than the newest as out of order and one at or
  // before the newest keyframe as late; false for both.
  bool AcceptWheelStamp(int64_t t_ns);
  bool AddGnss(const sensors::GnssFix& fix);
  bool AddGnss(const GnssPosition& position);
  bool AddSweep(lidar::LidarSweep sweep);
  bool AddKeyframeAt(int64_t t_ns);

  const SlidingWindowState& latest_state() const;
  std::vector<SlidingWindowState> Trajectory() const;
  std::vector<SlidingWindowState> SmoothedTrajectory(const sensors::Calibration& calibration) const;
  const sensors::Calibration& calibration() const { return calibration_; }
  CalibrationCovariance ComputeCalibrationCovariance(double min_reciprocal_condition_number);
  std::vector<FixedDirectionMove> FixedDirectionsTheStreamMoves(std::vector<EstimatedBlock> fixed,
                                                                double max_sigmas);
  int window_size() const { return static_cast<int>(window_.size()); }
  int pending_sweeps() const {
    return static_cast<int>(pending_sweeps_.size() + pending_times_.size());
  }
  bool has_marginalization_prior() const { return prior_ != nullptr; }
  const SlidingWindowCounters& counters() const { return counters_; }
  // Throws autocal::Error naming the failed update's error once an update has thrown.
  void RequireUsable() const;
  const SlidingWindowUpdateTiming& last_update_timing() const { return timing_; }
  int last_associated_points() const { return last_associated_points_; }
  double last_point_rms_m() const;
  GnssNoiseFromResiduals gnss_noise() const { return gnss_rows_.Noise(); }
  GnssStdScale gnss_std_scale() const;
  GnssStdScale largest_gnss_std_scale() const { return largest_gnss_std_scale_; }

 private:
  struct WindowKeyframe;
  struct ProblemBuild;
  struct SmoothingStep;

  // Where the keyframes come from: decided by the first AddSweep or AddKeyframeAt.
  enum class KeyframeSource { kUndecided, kSweeps, kTimes };
  // Sets the source, or throws autocal::Error when the window already takes the other one.
  // Keyframes from times hold the LiDAR blocks (options_.estimate and their priors).
  void UseKeyframeSource(KeyframeSource source);

  // A sweep with its points' span, read from its cloud once when it arrives (SpanOf) and kept
  // with it until its keyframe holds it.
  struct SpannedSweep {
    lidar::LidarSweep sweep;
    SweepSpan span;
  };
  int64_t KeyframeTimeOf(const SpannedSweep& sweep) const;
  int64_t MinKeyframeIntervalNs() const;  // options_.min_keyframe_interval_s, at least 1 ns
  // A keyframe at t_ns would not follow the newest one by min_keyframe_interval_s (dropped as
  // late).
  bool TooCloseToNewestKeyframe(int64_t t_ns) const;
  // No IMU sample lies strictly between the newest keyframe and t_ns (an IMU dropout, or an IMU
  // slower than min_keyframe_interval_s): the IMU factor over the interval would be one
  // interpolated step, whose position and velocity share one noise draw (a singular
  // covariance). Such a keyframe is skipped (counters.without_imu) and the next one spans the
  // dropout.
  bool NoImuSinceNewestKeyframe(int64_t t_ns) const;
  void ProcessCoveredSweeps();
  void ProcessCoveredTimes();
  // One window update for a new keyframe at t_ns, with its sweep when it has one (t_ns is then
  // KeyframeTimeOf(*sweep)). An update that throws leaves the window between two states (the
  // keyframe and its samples taken in, the solve or the marginalization not done): the error
  // is kept, and RequireUsable refuses every later call with it.
  void Update(int64_t t_ns, std::optional<SpannedSweep> sweep);
  void UpdateWindow(int64_t t_ns, std::optional<SpannedSweep> sweep);
  // The keyframe at t_ns predicted with the IMU, its sweep's chosen points, and the factors
  // of the interval before it.
  void AddKeyframe(int64_t t_ns, std::optional<SpannedSweep> sweep);
  void SetSweepPoints(SpannedSweep sweep, WindowKeyframe* kf) const;
  // Wheel (every form) and GNSS factors for the buffered samples in (from, t_end_ns],
  // attached to `from`.
  void AttachIntervalMeasurements(WindowKeyframe* from, int64_t t_end_ns);
  void AttachPlanarRotationFactor(WindowKeyframe* from);
  void AttachWheelFactors(WindowKeyframe* from, int64_t t_end_ns);
  void AttachWheelSpeedFactors(WindowKeyframe* from, int64_t t_end_ns);
  void AttachOdometryFactors(WindowKeyframe* from, int64_t t_end_ns);
  sensors::GyroMean GyroAround(int64_t t_ns) const;
  struct RowBodyRate {
    Eigen::Vector3d rate_rad_s;
    factors::WheelFactorOptions rows;
    double yaw_sigma_rad_s = 0.0;
    // What the speed row adds to its encoder or wheel-speed variance, given apart to the forms
    // that whiten that row at their current scales (the odometry form has it in
    // rows.speed_sigma_m_s): the rate's remaining error through the lever arm (Eq. K13,
    // BodyRateAround) and the propagated velocity's variance (Eq. W7, AttachPropagated).
    double speed_variance_m2_s2 = 0.0;
  };
  RowBodyRate BodyRateAround(int64_t t_ns, const factors::WheelFactorOptions& rows) const;
  // Adds the body rate the wheel rows take at the keyframe (BodyRateAround) to turning_rates_
  // and updates yaw_axis_I_.
  void UpdateTurningAxis(const WindowKeyframe& from);
  double GyroSampleSigma() const;
  double GyroMeanSigma(const sensors::GyroMean& gyro) const;
  internal::AttachedFactor WheelRowFactor(ceres::CostFunction* cost, SlidingWindowState* s,
                                          std::initializer_list<double*> blocks,
                                          const char* what) const;
  double NonHolonomicScale(size_t used, int64_t t_from_ns, int64_t t_end_ns) const;
  factors::WheelFactorOptions NonHolonomicRows(factors::WheelFactorOptions options,
                                               double scale) const;
  template <typename Sample>
  std::vector<Sample> TakeThinned(std::deque<Sample>* queue, int64_t t_end_ns) const;
  template <typename Sample, typename Make>
  void AttachPropagated(WindowKeyframe* from, const std::vector<Sample>& used, int64_t t_end_ns,
                        const factors::WheelFactorOptions& form_rows, bool speed_row_by_options,
                        Make make) const;
  void RelinearizeImuFactors();
  // Refreshes the plane maps that moved and makes the pairing tries that are missing or stale
  // (SweepPairing).
  void AssociatePoints();
  // The window problem: keyframes, calibration blocks, IMU/wheel/GNSS factors, priors and the
  // keyframes' point groups. The point groups are linearized afresh, or, given their motions
  // (PointGroupMotions, in its order; a later pass of an update), only those that moved by
  // more than relinearization_tolerance_m since their linearization.
  std::unique_ptr<ProblemBuild> BuildProblem(const std::vector<double>* group_motions = nullptr);
  void AddPointGroups(ProblemBuild* build, const std::vector<double>* group_motions);
  // Solves; replaces *build with each later pass's problem, the point groups that moved
  // relinearized where the previous pass ended.
  void Solve(std::unique_ptr<ProblemBuild>* build);
  // Per point group of the window, in the order of the keyframes and their groups: how far
  // its two sweeps moved relative to each other since its linearization (infinite when it has
  // none).
  std::vector<double> PointGroupMotions() const;
  // Sum of the squared point-to-plane distances (m^2, without the loss) at the current
  // estimate of the point groups of the window (only those that pair a sweep with the oldest
  // keyframe's, either way round, if so asked).
  double SquaredPointDistances(bool oldest_only) const;
  std::unique_ptr<MarginalizationPrior> MarginalizeOldest(ProblemBuild* build);
  // The same marginalization with options_.tested_fixed_blocks free and tested_prior_ in place
  // of prior_: the prior that carries the stream's information on the fixed blocks too. Its
  // part on the other kept blocks is prior_'s (the Schur complement does not depend on which
  // other blocks are kept) up to the directions each drops as without information. Leaves
  // `build` unfit for anything but being dropped.
  std::unique_ptr<MarginalizationPrior> MarginalizeOldestWithTestedBlocks(ProblemBuild* build);
  // MarginalizeOldestWithTestedBlocks when there are tested blocks and their chain holds
  // (main_prior: the window's marginalization kept a prior); a failure sets untested_reason_,
  // which ends the chain, instead of stopping the estimate.
  std::unique_ptr<MarginalizationPrior> CarryTestedBlocks(ProblemBuild* build, bool main_prior);
  // Replaces prior_'s residual block in `problem` by tested_prior_'s (none when it is null).
  void SwapInTestedPrior(ceres::Problem* problem) const;
  // With options_.smoothing: keeps the oldest keyframe's conditional for SmoothedTrajectory().
  void RecordSmoothingStep(MarginalConditional conditional);
  void DropOldest(std::unique_ptr<MarginalizationPrior> prior);
  // Eq. N2: the oldest keyframe's GNSS rows at the estimate into gnss_rows_ (a row that cannot
  // be evaluated is left out).
  void RecordGnssRowsOfOldest();
  void TrimImuBuffer();
  void AddCalibrationPriors(const sensors::Calibration& initial_calibration);

  SlidingWindowOptions options_;
  Eigen::Vector3d g_W_;
  sensors::Calibration calibration_;
  geometry::RightQuaternionManifold quaternion_manifold_;
  std::optional<sensors::EnuConverter> enu_;
  // One loss per sensor (nullptr = plain least squares), shared by its residual blocks.
  std::unique_ptr<ceres::LossFunction> imu_loss_;
  std::unique_ptr<ceres::LossFunction> wheel_loss_;
  std::unique_ptr<ceres::LossFunction> gnss_loss_;
  std::unique_ptr<ceres::LossFunction> prior_loss_;

  sensors::ImuSamples imu_;  // from the oldest window keyframe or its sweep on (TrimImuBuffer)
  std::deque<sensors::WheelSample> wheel_;
  std::deque<sensors::WheelSpeedSample> wheel_speeds_;
  std::deque<sensors::OdometrySample> odometry_;
  std::deque<GnssPosition> gnss_;
  // The keyframes' body rates so far and the turning axis they give (zero: none yet), which
  // the wheel rows of later intervals read their yaw rate about (Eq. K13c).
  internal::TurningRateSpread turning_rates_;
  Eigen::Vector3d yaw_axis_I_ = Eigen::Vector3d::Zero();
  std::deque<SpannedSweep> pending_sweeps_;
  std::deque<int64_t> pending_times_;  // AddKeyframeAt
  KeyframeSource keyframe_source_ = KeyframeSource::kUndecided;
  int64_t newest_wheel_ns_;
  int64_t newest_gnss_ns_;
  int64_t newest_sweep_ns_;
  int64_t newest_time_ns_;

  std::deque<std::unique_ptr<WindowKeyframe>> window_;
  // The pairing's try buffer of the keyframe last marginalized (a megabyte at thousands of
  // points), which the next keyframe takes over instead of allocating it afresh.
  std::vector<int> spare_tried_at_;
  int next_keyframe_id_ = 0;
  std::vector<SlidingWindowState> marginalized_;
  std::vector<SmoothingStep> smoothing_;  // one per marginalized_, with options_.smoothing
  // Prior of the marginalized keyframes; replaced by every marginalization.
  std::unique_ptr<MarginalizationPrior> prior_;
  // prior_ with the tested fixed blocks' information (options_.tested_fixed_blocks), for
  // FixedDirectionsTheStreamMoves; null without them or once their chain ended.
  std::unique_ptr<MarginalizationPrior> tested_prior_;
  std::string untested_reason_;  // why the tested blocks' chain ended; empty while it holds
  // The marginalized GNSS rows whitened by the fixes' stated std (Eq. N2 over them:
  // gnss_noise()).
  GnssRowScatter gnss_rows_;
  GnssStdScale largest_gnss_std_scale_;  // over the fixes attached so far
  std::vector<internal::AttachedFactor> calibration_priors_;
  // The solver's dense buffers, kept from update to update.
  internal::WindowSolverWorkspace solver_workspace_;
  // The pairing engine, with the point groups' storage.
  internal::SweepPairing pairing_;

  SlidingWindowCounters counters_;
  std::string failed_update_;  // the error of an update that threw (Update)
  SlidingWindowUpdateTiming timing_;
  // q_I_L after each of the last window_size updates (the pairing's gate).
  std::deque<Eigen::Quaterniond> recent_q_I_L_;
  int last_associated_points_ = 0;
  // Squared distances of the groups the last update's marginalization dropped; the RMS once
  // evaluated.
  double dropped_point_squared_m2_ = 0.0;
  mutable std::optional<double> last_point_rms_m_ = 0.0;
};

struct SlidingWindowEstimator::Impl::WindowKeyframe {
  int id = 0;
  SlidingWindowState state;
  // The sweep that made this keyframe (none for the initial keyframe) and its chosen points.
  std::optional<lidar::LidarSweep> sweep;
  SweepSpan sweep_span;
  internal::ResidualPoints residuals;
  std::vector<int> map_points;
  // Preintegration from the previous keyframe (none for the oldest in the window).
  std::unique_ptr<sensors::ImuPreintegration> imu_from_previous;
  // Factors on this keyframe alone (or with calibration blocks): the initial-state prior,
  // wheel and GNSS samples of the interval that starts here.
  std::vector<internal::AttachedFactor> factors;
  // The sweep's plane map, its points' pairing state and their groups (SweepPairing).
  internal::SweepMap map;
  internal::PairingState pairing;
  std::vector<internal::SweepPointGroup> point_groups;
};

inline const SlidingWindowState& SlidingWindowEstimator::Impl::latest_state() const {
  return window_.back()->state;
}

// A marginalized keyframe's conditional (Eq. M4) and what its kept blocks were: a block of
// a keyframe (by id, and index in StateBlocks) or a calibration block (its address in the
// estimator's calibration, keyframe_id -1).
struct SlidingWindowEstimator::Impl::SmoothingStep {
  struct BlockRef {
    int keyframe_id = -1;
    int state_block = 0;
    const double* calibration = nullptr;
  };
  int keyframe_id = 0;
  MarginalConditional conditional;
  std::vector<int> marginalized;  // index in StateBlocks of each conditional's marginalized block
  std::vector<BlockRef> kept;
};

// One window problem and the cost functions it alone uses (the problem owns nothing).
struct SlidingWindowEstimator::Impl::ProblemBuild {
  std::vector<std::unique_ptr<ceres::CostFunction>> owned;
  std::unique_ptr<ceres::Problem> problem;
  // The rows the solver evaluates at every iteration: the IMU factors, the rows with a robust
  // loss and, without linearization per pass, every row.
  std::vector<ceres::ResidualBlockId> relinearized;
};

namespace internal {

// One calibration block as the window problem holds it: a quaternion (ambient 4, tangent 3,
// RightQuaternionManifold) or a Euclidean block.
struct CalibrationBlock {
  const char* name;  // as in CalibrationCovariance::names
  double* values;
  int ambient_size;
  int tangent_size;
  bool estimated;
};

// The calibration's blocks in the order of CalibrationCovariance: the block table's
// (sensors/calibration_blocks.h).
inline std::vector<CalibrationBlock> CalibrationBlocks(sensors::Calibration* c,
                                                       const SlidingWindowEstimatedBlocks& e) {
  std::vector<CalibrationBlock> blocks;
  for (const sensors::CalibrationBlockInfo& info : sensors::CalibrationBlocks()) {
    blocks.push_back(
        {info.key, info.values(c), info.ambient_size, info.tangent_size, Estimated(info.id, e)});
  }
  return blocks;
}

// The five state blocks of a keyframe, in the order the IMU factor and the priors take them.
inline std::vector<double*> StateBlocks(SlidingWindowState* s) {
  return {s->q_W_I.coeffs().data(), s->p_W_I.data(), s->v_W_I.data(), s->b_g.data(), s->b_a.data()};
}

// Throws autocal::Error naming the first invalid option (sliding_window_options.cc).
void CheckOptions(const SlidingWindowOptions& options);

// options.pairing without the partner offsets the window can never hold (|offset| >
// window_size; while it pairs, the new keyframe is in and the oldest not yet out): a library
// default or a list written for a longer window still pairs, its settled walk over the first
// offsets that remain.
PairingOptions PairingWithinWindow(const SlidingWindowOptions& options);

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
