#pragma once

// Online sliding-window estimator (docs/sliding_window.md): IMU preintegration, wheel, GNSS
// and LiDAR point-to-plane factors (a point of one window sweep against a plane of another)
// over the last N keyframes, the calibration blocks shared by all of them, and the older
// keyframes marginalized into a linear prior.
//
// Data is streamed in with AddImu / AddWheel / AddGnss / AddSweep. Every LiDAR sweep becomes
// a keyframe once the IMU covers it, and each new keyframe triggers one window update: predict
// it with the IMU, attach the interval's IMU, wheel and GNSS factors, pair the window's points
// with planes of other window sweeps (estimation/pairing_options.h), solve, and marginalize
// the oldest keyframe when the window holds more than N.
//
// Without a LiDAR the keyframes come from AddKeyframeAt instead (e.g. at a fixed period): the
// same update without point rows, so IMU, wheels and GNSS alone carry the window.

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "autocal/estimation/calibration_observability.h"
#include "autocal/estimation/gnss_noise.h"
#include "autocal/estimation/lidar_inertial_batch.h"
#include "autocal/estimation/sliding_window_options.h"
#include "autocal/lidar/point_cloud.h"
#include "autocal/sensors/calibration.h"
#include "autocal/sensors/measurements.h"

namespace autocal {
namespace estimation {

// One keyframe's state with its time (IMU clock) — the same fields as the batch solver's.
using SlidingWindowState = Keyframe;

// A GNSS antenna position already in W (e.g. from sensors::EnuConverter).
struct GnssPosition {
  int64_t t_ns = 0;  // IMU clock
  Eigen::Vector3d p_W_A = Eigen::Vector3d::Zero();
  Eigen::Vector3d sigma_enu_m = Eigen::Vector3d::Ones();
};

// Counters of the streaming rules (docs/sliding_window.md, "Ordering rule").
struct SlidingWindowCounters {
  int64_t imu_accepted = 0;
  int64_t wheel_accepted = 0;
  int64_t gnss_accepted = 0;
  int64_t sweeps_accepted = 0;
  int64_t keyframe_times_accepted = 0;  // AddKeyframeAt
  int64_t out_of_order = 0;             // not newer than the newest of their stream (dropped)
  int64_t late = 0;                     // at or before the newest keyframe (dropped)
  int64_t late_gnss = 0;                // of them, GNSS fixes
  // Keyframes (sweeps or times) skipped: no IMU sample between them and the newest keyframe
  // (an IMU dropout); the next keyframe's IMU factor spans the dropout.
  int64_t without_imu = 0;
  int64_t updates = 0;  // keyframes added (= window updates)
  int64_t marginalizations = 0;
  int64_t gnss_scaled = 0;  // fixes attached with their std scaled (Eq. N2)
};

// Timing of the last update (seconds, wall clock).
struct SlidingWindowUpdateTiming {
  double total_s = 0.0;
  double association_s = 0.0;  // plane maps and pairing
  double build_s = 0.0;        // the window problem (first pass; later passes are in solve_s)
  double solve_s = 0.0;
  double marginalization_s = 0.0;
  int solver_iterations = 0;       // Levenberg-Marquardt steps taken (all passes)
  int solver_passes = 0;           // linearizations of the points
  int plane_lookups = 0;           // k-NN plane lookups
  bool extrinsic_settled = false;  // new keyframes tried settled_partner_count partners
};

// Covariance of the estimated calibration blocks in tangent coordinates (right-perturbed
// rotations), blocks in the order of `names` starting at `offsets`.
struct CalibrationCovariance {
  std::vector<std::string> names;  // e.g. "q_I_L", "p_I_L", "time_offset_lidar_imu_s"
  std::vector<int> offsets;
  Eigen::MatrixXd covariance;
};

class SlidingWindowEstimator {
 public:
  // `initial_state` is keyframe 0, in W at its IMU time t_ns. Throws autocal::Error on
  // invalid options.
  SlidingWindowEstimator(const SlidingWindowOptions& options,
                         const sensors::Calibration& initial_calibration,
                         const SlidingWindowState& initial_state);
  ~SlidingWindowEstimator();
  SlidingWindowEstimator(const SlidingWindowEstimator&) = delete;
  SlidingWindowEstimator& operator=(const SlidingWindowEstimator&) = delete;

  // Streaming input, each stream in increasing time. A sample not newer than the newest
  // accepted one of its stream is dropped (out_of_order); a wheel/GNSS sample or a sweep at or
  // before the newest keyframe's time is dropped (late). Returns whether the datum was
  // accepted. Non-finite values throw autocal::Error. AddImu and AddSweep process every
  // buffered sweep the IMU now covers (one update per sweep). An update that fails (its solve
  // or marginalization throws autocal::Error) leaves the window between two states: from then
  // on every streaming call, ComputeCalibrationCovariance and FixedDirectionsTheStreamMoves
  // throw autocal::Error with that update's error.
  bool AddImu(const sensors::ImuSample& sample);
  bool AddWheel(const sensors::WheelSample& sample);
  // Wheels as the rear pair's linear speeds (Eq. F25).
  bool AddWheelSpeeds(const sensors::WheelSpeedSample& sample);
  // Wheels as the controller's twist (Eq. F26); options.wheel.controller_track_m must be set.
  bool AddOdometry(const sensors::OdometrySample& sample);
  bool AddGnss(const sensors::GnssFix& fix);
  bool AddGnss(const GnssPosition& position);
  bool AddSweep(lidar::LidarSweep sweep);  // an rvalue is moved in, not copied
  // A keyframe at IMU time t_ns without a sweep, for a window without the LiDAR: made once the
  // IMU covers t_ns plus imu_coverage_margin_s, by the same update as a sweep's keyframe minus
  // the point rows. Nothing then constrains the LiDAR blocks (q_I_L, p_I_L, the LiDAR time
  // offset), so such a window holds them at their initial value whatever options.estimate says
  // (no prior, not in ComputeCalibrationCovariance). A window takes its keyframes from sweeps
  // or from this, never both (the first call decides; the other then throws autocal::Error).
  // A time not after the last one asked for is dropped (out_of_order), one within
  // min_keyframe_interval_s of the newest keyframe, or of the newest time still waiting for
  // the IMU, too (late).
  bool AddKeyframeAt(int64_t t_ns);

  const SlidingWindowState& latest_state() const;
  // Every keyframe so far in time order: marginalized ones as last estimated in the window,
  // the window's at their current estimate.
  std::vector<SlidingWindowState> Trajectory() const;
  // The same keyframes smoothed by a backward pass over the marginalizations
  // (docs/sliding_window.md, "Smoothing"). Needs options.smoothing (throws otherwise).
  std::vector<SlidingWindowState> SmoothedTrajectory() const;
  // The same pass given another calibration than the window's (one with held directions,
  // Eq. C1): every marginalized keyframe follows it through its conditional. The window's
  // keyframes stay at their estimate.
  std::vector<SlidingWindowState> SmoothedTrajectory(const sensors::Calibration& calibration) const;
  const sensors::Calibration& calibration() const;
  // Covariance of the estimated calibration blocks given the window problem (point groups
  // linearized afresh at the current estimate), a pseudo-inverse that gives unobservable directions
  // zero variance (singular values s of J with (s / s_max)^2 below
  // min_reciprocal_condition_number are dropped). Not const: Ceres evaluates through the
  // estimator's blocks (their values do not change). Throws autocal::Error when Ceres fails.
  CalibrationCovariance ComputeCalibrationCovariance(
      double min_reciprocal_condition_number = 1e-12);
  // Eq. C7 over the whole stream: the fixed blocks among `fixed` that options.
  // tested_fixed_blocks names (their data pointers are rebound to the window's blocks; their
  // priors centre at the held values) tested on the final window with the marginalized
  // keyframes' information on them (FixedDirectionsTheDataMove, Gauss-Newton sigma): the
  // directions the stream would move by more than max_sigmas sigmas. Throws autocal::Error
  // when that information was lost on the way (a second marginalization failed; the estimate
  // went on without it). Not const, as ComputeCalibrationCovariance.
  std::vector<FixedDirectionMove> FixedDirectionsTheStreamMoves(std::vector<EstimatedBlock> fixed,
                                                                double max_sigmas);

  int window_size() const;     // keyframes currently in the window
  int pending_sweeps() const;  // sweeps or AddKeyframeAt times waiting for the IMU
  bool has_marginalization_prior() const;
  const SlidingWindowCounters& counters() const;
  const SlidingWindowUpdateTiming& last_update_timing() const;
  // Point-to-plane residuals of the last update and their RMS after its solve (metres,
  // without the loss; evaluated on the first call after an update).
  int last_associated_points() const;
  double last_point_rms_m() const;
  // Eq. N2 over the GNSS rows marginalized so far (SlidingWindowOptions::
  // gnss_noise_from_residuals): their robust sigma, their count and the scale the next fix
  // takes (1 below kMinGnssNoiseRows rows).
  GnssNoiseFromResiduals gnss_noise() const;
  // The scale the next fix's stated std takes: per axis group, gnss_noise()'s from
  // kMinGnssNoiseRows rows on, options.gnss_std_scale before.
  GnssStdScale gnss_std_scale() const;
  // The largest scale an attached fix's stated std took, per axis group: the rows' scatter can
  // exceed the threshold over part of the stream and fall below it by the end.
  GnssStdScale largest_gnss_std_scale() const;

 private:
  class Impl;  // estimation/sliding_window_internal.h
  std::unique_ptr<Impl> impl_;
};

}  // namespace estimation
}  // namespace autocal
