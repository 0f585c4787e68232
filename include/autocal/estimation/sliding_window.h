#pragma once

// Online sliding-window estimator (docs/sliding_window.md): IMU preintegration, wheel,
// GNSS and LiDAR point-to-plane factors (a point of one window sweep against a plane of
// another) over the last N keyframes, the calibration blocks shared by all of them, and the
// older keyframes marginalized into a linear prior.
//
// Data is streamed in with AddImu / AddWheel / AddGnss / AddSweep. Every LiDAR sweep becomes
// a keyframe once the IMU covers it; each new keyframe triggers one window update:
//   1. predict the keyframe with the IMU from the previous one,
//   2. attach the IMU factor and the wheel/GNSS samples of the interval,
//   3. pair the keyframes' residual points with planes of other window sweeps, one residual
//      block per pair of sweeps; each sweep's plane map is kept in its LiDAR frame, so the
//      planes move with that keyframe and the extrinsic. The new keyframe is paired at once,
//      an older one in full when a partner moved relative to it, else only its points whose
//      partner left and the sweeps that entered; a plane map is rebuilt only when its deskew
//      moved (docs/sliding_window.md, "Reuse between updates"),
//   4. solve, with the point groups linearized per pass (Eq. SW7),
//   5. marginalize the oldest keyframe when the window holds more than N.

#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "autocal/estimation/keyframe.h"
#include "autocal/estimation/marginalization.h"
#include "autocal/factors/loss.h"
#include "autocal/geometry/manifolds.h"
#include "autocal/lidar/plane_map.h"
#include "autocal/lidar/point_cloud.h"
#include "autocal/sensors/calibration.h"
#include "autocal/sensors/gnss_enu.h"
#include "autocal/sensors/imu_preintegration.h"
#include "autocal/sensors/measurements.h"
#include "autocal/sensors/sensor_config.h"

namespace autocal {
namespace estimation {

namespace internal {
struct AttachedFactor;
struct WindowSolverWorkspace;
}  // namespace internal

// Which calibration blocks the window estimates; the others are held at their initial value.
struct SlidingWindowEstimatedBlocks {
  bool extrinsic_rotation = true;     // q_I_L
  bool extrinsic_translation = true;  // p_I_L
  bool time_offset = true;            // time_offset_lidar_imu_s
  bool wheel_radii = true;            // wheel_radius_left_m, wheel_radius_right_m
  bool track_width = true;            // track_width_m
  bool vehicle_frame = false;         // q_I_V, p_I_V (weakly observable from wheel data)
  bool gnss_lever_arm = true;         // p_I_A
};

// The priors that tie each estimated calibration block to a prior value, with these 1-sigma.
// They are added once and never marginalized, so they regularize directions the first
// seconds of driving do not excite.
struct SlidingWindowCalibrationPrior {
  // The value the priors are centred at: the calibration the sigmas belong to, such as a
  // hand-measured nominal one. Unset: the estimator's initial calibration. A starting value
  // estimated from the same log (the initializer's) is no prior: centred there, the sigmas
  // would count its data twice and hold on to its error (docs/sliding_window.md, "Calibration
  // priors").
  std::optional<sensors::Calibration> mean;
  double extrinsic_rotation_deg = 3.0;
  double extrinsic_translation_m = 0.1;
  double time_offset_s = 0.01;
  double wheel_radius_m = 0.01;
  double track_width_m = 0.05;
  double vehicle_rotation_deg = 2.0;
  double vehicle_translation_m = 0.1;
  double gnss_lever_arm_m = 0.2;
};

// 1-sigma of the prior on the initial state (the gauge: position and yaw are unobservable
// from IMU and LiDAR alone, so the first keyframe anchors the window until GNSS does).
struct SlidingWindowInitialStateSigmas {
  double rotation_deg = 0.01;
  double position_m = 0.001;
  double velocity_m_s = 0.01;
  double gyro_bias_rad_s = 2e-3;
  double accel_bias_m_s2 = 3e-2;
};

struct SlidingWindowOptions {
  // Keyframes kept in the window; the oldest beyond this is marginalized. Keyframe policy:
  // every LiDAR sweep becomes a keyframe (plus the initial state, keyframe 0).
  int window_size = 10;

  // Noise of the sensors (sensors/sensor_config.h).
  sensors::ImuConfig imu;
  sensors::WheelConfig wheel;
  // Robust loss per sensor, on whitened residuals (factors/loss.h).
  factors::FactorLossOptions loss;
  SlidingWindowEstimatedBlocks estimate;
  SlidingWindowCalibrationPrior calibration_prior;
  SlidingWindowInitialStateSigmas initial_state_sigmas;

  // Wheel factors: non-holonomic rows and their sigma. The speed and yaw-rate rows are
  // whitened with `wheel.noise_rad_s` and the gyro's sample noise at the current radii and
  // track width (docs/sliding_window.md, Eq. SW1-SW2). At most this many wheel samples per
  // keyframe interval are used (evenly spread; 0 = all). The non-holonomic rows (no lateral
  // or vertical speed of the rear axle) are off by default: the simulated rear axle moves
  // sideways and vertically by up to 0.14 m/s, and with the LiDAR pairs moving with the
  // extrinsic the rows pulled p_I_L up to 0.7 m forward (docs/sliding_window.md, "Figures"),
  // as white rows. Their sigma is scaled for the model error's correlation time as the
  // offline calibration's (Eq. K6, estimation::NonHolonomicSigmaScale), dt the spacing of the
  // interval's wheel samples used: 2 s at 5 samples per 0.1 s makes 0.05 m/s 0.71 m/s, and so
  // weighted they keep the vehicle frame and the radii out of their cosine valley
  // (pipeline::EstimateDatasetOnline turns them on). 0 keeps the rows white.
  bool wheel_non_holonomic = false;
  double wheel_non_holonomic_sigma_m_s = 0.05;
  double wheel_non_holonomic_correlation_s = 2.0;
  int max_wheel_samples_per_interval = 5;
  // The angular rate the wheel rows take (in the rear axle's lever-arm speed w x p_I_V and the
  // yaw-rate row, Eq. F22): the mean gyro over this span centred on the wheel sample, its
  // sample noise divided by sqrt(n) in the yaw-rate whitening (0: the gyro interpolated at the
  // sample). One sample's noise, times the rear axle's 1.2 m lever, is noise in a regressor of
  // p_I_V, which least squares shrinks towards the IMU (errors in variables): on the 60 s
  // urban logs the rear axle's height ended 38-40 cm off, and p_I_L's height 4-10 cm with it.
  // 50 ms (11 samples at 200 Hz) left 3-6 cm and 0.5-4 cm (docs/sliding_window.md, Eq. SW10).
  double wheel_gyro_mean_span_s = 0.05;

  // GNSS: origin of W for AddGnss(GnssFix) (WGS84 latitude, longitude, ellipsoidal height).
  // Unset: W is the ENU frame at the first fix received (docs/design.md), so the initial
  // state must be given in that frame.
  std::optional<Eigen::Vector3d> enu_origin_lla;

  // LiDAR keyframes sit this long before their sweep's first point (IMU clock, at the time
  // offset estimate when the sweep arrives), so that the offset may move earlier by this much.
  double keyframe_lead_s = 0.02;
  // A sweep is processed when the IMU covers its last point at the current offset plus this
  // margin (room for the offset estimate to grow).
  double imu_coverage_margin_s = 0.02;
  // A sweep whose keyframe would follow the newest keyframe by less than this is dropped as
  // late: an IMU factor over less than two IMU samples has a singular covariance (the
  // position error of one sampled step is a fixed multiple of its velocity error).
  double min_keyframe_interval_s = 0.02;
  // Residual points of each sweep: one per voxel of this size (in L), no farther than
  // residual_max_range_m, then at most max_residuals_per_sweep. Beyond about 40 m the default
  // 32-beam LiDAR's rings lie a metre apart, so a local plane of map points within
  // plane_map.max_neighbor_distance_m is rarely found there (docs/sliding_window.md, "Far
  // points"); raise it for a denser LiDAR. 0: no limit.
  double residual_voxel_m = 0.6;
  double residual_max_range_m = 40.0;
  int max_residuals_per_sweep = 2000;
  // Points of each sweep that build the plane map (one per voxel of this size).
  double map_voxel_m = 0.3;
  double min_range_m = 2.0;  // closer points (the car itself) are ignored
  // Association (docs/sliding_window.md, "Association"): a residual point of window keyframe
  // k is paired with a plane of the sweep of keyframe k + o, for the first offset o (in
  // keyframes) that gives one. Partners a few sweeps apart have moved relative to the point's
  // sweep, which makes the extrinsic and time offset observable; they must still overlap it,
  // and lie in the window. A point tries the first settled_partner_count offsets, starting at
  // a different one for consecutive points, then the others likewise; the points of a
  // keyframe first paired once the extrinsic rotation had settled try only the first
  // settled_partner_count (Eq. SW15). Settled: window_size updates have been made and q_I_L
  // moved by at most settled_extrinsic_deg over the last window_size. While the extrinsic is
  // degrees off, a wrong extrinsic places the points of distant sweeps too far off for their
  // planes and nearer sweeps pair them; once it has settled, the pairs five sweeps apart
  // determine it as well as all of them, at a third of the plane lookups.
  std::vector<int> partner_keyframe_offsets = {-5, 5, -8, 8, -3, 3, -2, 2};
  int settled_partner_count = 2;
  double settled_extrinsic_deg = 0.5;
  // Local plane fitting in each sweep's map.
  lidar::PlaneMapOptions plane_map;
  // Outlier gate: a point farther than this from the plane found for it is not associated
  // (moving objects, edges, planes fitted across a corner).
  double max_point_to_plane_m = 0.1;
  // A residual point whose last max_plane_misses plane lookups, in any partner sweeps, found
  // no plane (fewer than num_neighbors map points within the neighbour radius, or a
  // neighbourhood that fails the plane gates) is not looked up again until its own sweep's
  // plane map is rebuilt (its deskew moved), and so finds no new pair (a pair it holds is
  // still looked up again when its try goes stale, and only a lookup ends it): such points mostly lie
  // on clutter, edges or sparse far ground, which the other sweeps see alike (docs/
  // sliding_window.md, "Points without a plane"). Fewer misses save more lookups but drop the
  // sparse far ground, which pins the rotation. 0: every point is looked up in every partner
  // it walks.
  int max_plane_misses = 6;
  // While the extrinsic rotation is still converging the gate widens with it (docs/
  // sliding_window.md, Eq. SW14): a point at range r is associated within
  //   max_point_to_plane_m + gate_extrinsic_factor * max(0, angle - gate_extrinsic_free_deg) * r
  // of its plane, `angle` the rotation of q_I_L over the last window_size updates. A gate
  // fixed at a decimetre keeps only the points that a wrong extrinsic happens to place near
  // their planes, and the window can then drive the extrinsic the wrong way.
  // gate_extrinsic_factor 0: a fixed gate.
  double gate_extrinsic_factor = 0.25;
  double gate_extrinsic_free_deg = 0.5;
  // Reuse between updates (docs/sliding_window.md, "Reuse between updates", Eq. SW4): a
  // point's try against a partner sweep (a plane found or none) holds while both sweeps' maps
  // are unchanged and their relative pose has moved by at most reassociation_tolerance_m at
  // the point's range; only missing and stale tries are made again. A sweep's plane map is
  // rebuilt when the deskew at the current estimate moves one of its points by more than
  // map_rebuild_tolerance_m. 0 = at every update.
  double reassociation_tolerance_m = 0.02;
  double map_rebuild_tolerance_m = 0.02;
  // A keyframe whose walked partners are in the window as at its last pairing, with every try
  // holding at its farthest residual point's range, is not walked again: its pairs stay (the
  // walk would make no lookup and change nothing). false walks every keyframe (the same pairs,
  // for tests).
  bool skip_unchanged_keyframes = true;
  // 1-sigma of a point-to-plane distance (range noise and plane fit).
  double point_sigma_m = 0.03;

  // Point groups, wheel and GNSS rows linearized per solve pass (docs/sliding_window.md,
  // Eq. SW7): the solver iterates on their first-order model at the pass's start, so an
  // iteration does not re-evaluate their Jacobians (the point groups' and the wheel and GNSS
  // rows' automatic derivatives through the IMU propagation); an update runs up to this many
  // passes, the first on every row linearized afresh, a later one (Eq. SW12, below) on the
  // point groups that moved relinearized where the previous pass ended. 0: one pass
  // evaluating them at every iteration (Eq. SW5).
  int point_linearizations_per_update = 2;
  // A further pass runs only when some point group's points moved by more than this since its
  // linearization: its two sweeps' relative motion at the range of the keyframe's farthest
  // residual point, plus the change of their deskew (docs/sliding_window.md, Eq. SW12); it
  // relinearizes those groups, whose linearization and loss weights hold until then. The
  // wheel and GNSS rows are relinearized only by a further pass. 0 = always
  // point_linearizations_per_update passes, every group relinearized.
  double relinearization_tolerance_m = 0.01;
  // Solver stop: at most solver_iterations Levenberg-Marquardt iterations per pass, fewer once
  // an iteration lowers the cost by less than this fraction of it (ceres function_tolerance).
  // The window starts from the previous solution, so a few iterations usually suffice; the
  // cap matters while the calibration is still converging (docs/sliding_window.md, "Solver:
  // iterations": 1e-5 takes 3 iterations at the median where Ceres' 1e-6 took 8, with the
  // same accuracy; 1e-3 did not converge from the nominal calibration).
  int solver_iterations = 10;
  double solver_function_tolerance = 1e-5;
  // Threads of the association's per-sweep loops and of the covariance; the solve itself runs
  // on one (docs/sliding_window.md, "Solver: threads").
  int num_threads = 1;
  MarginalizationOptions marginalization;
  // Keep, for every marginalized keyframe, its state given the blocks it was marginalized
  // onto (Eq. M4: a 15-row gain over the next keyframe, the point pairs' partners and the
  // calibration, about 12 KB per keyframe with the defaults), so that
  // SmoothedTrajectory() can carry the final window's estimate back to every keyframe
  // (docs/sliding_window.md, "Smoothing"). Memory grows with the log: for offline runs.
  bool smoothing = false;
};

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
  // Samples not newer than the newest of their stream (dropped).
  int64_t out_of_order = 0;
  // Wheel/GNSS samples and sweeps at or before the newest keyframe, whose interval is
  // already solved (dropped).
  int64_t late = 0;
  int64_t updates = 0;          // keyframes added (= window updates)
  int64_t marginalizations = 0;
};

// Timing of the last update (seconds, wall clock).
struct SlidingWindowUpdateTiming {
  double total_s = 0.0;
  double association_s = 0.0;  // plane maps and association
  double build_s = 0.0;        // the window problem (first pass; later passes are in solve_s)
  double solve_s = 0.0;
  double marginalization_s = 0.0;
  int solver_iterations = 0;  // Levenberg-Marquardt steps taken (all passes)
  int solver_passes = 0;      // linearizations of the points (Eq. SW12)
  int plane_lookups = 0;      // k-NN plane lookups
  bool extrinsic_settled = false;  // points tried settled_partner_count partners (Eq. SW15)
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
  // invalid options (window_size < 2, non-positive sigmas or voxel sizes).
  SlidingWindowEstimator(const SlidingWindowOptions& options,
                         const sensors::Calibration& initial_calibration,
                         const SlidingWindowState& initial_state);
  ~SlidingWindowEstimator();
  // The marginalization prior points into the estimator's blocks: neither copy nor move.
  SlidingWindowEstimator(const SlidingWindowEstimator&) = delete;
  SlidingWindowEstimator& operator=(const SlidingWindowEstimator&) = delete;

  // Streaming input, each stream in increasing time. A sample not newer than the newest
  // accepted one of its stream is dropped (counted as out_of_order); a wheel/GNSS sample or
  // a sweep at or before the newest keyframe's time is dropped (counted as late). Returns
  // whether the datum was accepted. Non-finite values throw autocal::Error. AddImu and
  // AddSweep process every buffered sweep the IMU now covers (one update per sweep).
  bool AddImu(const sensors::ImuSample& sample);
  bool AddWheel(const sensors::WheelSample& sample);
  bool AddGnss(const sensors::GnssFix& fix);
  bool AddGnss(const GnssPosition& position);
  // A sweep passed as an rvalue is moved into the window, not copied.
  bool AddSweep(lidar::LidarSweep sweep);

  const SlidingWindowState& latest_state() const;
  // Every keyframe so far in time order: marginalized ones as last estimated in the window,
  // the window's at their current estimate.
  std::vector<SlidingWindowState> Trajectory() const;
  // The same keyframes smoothed (a Rauch-Tung-Striebel pass over the marginalizations,
  // docs/sliding_window.md, "Smoothing"): the window's at their current estimate, each
  // marginalized one, newest first, from its conditional (Eq. M4) at the smoothed values of
  // the blocks it was marginalized onto and the current calibration. Needs
  // SlidingWindowOptions::smoothing (throws autocal::Error otherwise).
  std::vector<SlidingWindowState> SmoothedTrajectory() const;
  const sensors::Calibration& calibration() const { return calibration_; }
  // Covariance of the estimated calibration blocks given the window problem (its factors,
  // the calibration priors and the marginalization prior, points re-associated at the
  // current estimate), computed with ceres::Covariance, DENSE_SVD and a Moore-Penrose
  // pseudo-inverse (null_space_rank = -1: singular values below
  // min_reciprocal_condition_number times the largest are dropped), so unobservable
  // directions get zero variance instead of failing. Not const: Ceres evaluates through the
  // estimator's blocks (their values are not changed; the point groups are linearized afresh
  // at them). Throws autocal::Error when Ceres fails.
  CalibrationCovariance ComputeCalibrationCovariance(double min_reciprocal_condition_number = 1e-12);

  int window_size() const;  // keyframes currently in the window
  int pending_sweeps() const { return static_cast<int>(pending_sweeps_.size()); }
  bool has_marginalization_prior() const { return prior_ != nullptr; }
  const SlidingWindowCounters& counters() const { return counters_; }
  const SlidingWindowUpdateTiming& last_update_timing() const { return timing_; }
  // Point-to-plane residuals of the last update and their RMS after its solve (metres,
  // without the loss). The RMS is evaluated on the first call after an update (the estimate
  // does not change in between), not by every update.
  int last_associated_points() const { return last_associated_points_; }
  double last_point_rms_m() const;

 private:
  struct WindowKeyframe;
  struct ProblemBuild;
  struct SmoothingStep;

  int64_t KeyframeTimeOf(const lidar::LidarSweep& sweep) const;
  // Its keyframe would not follow the newest one by min_keyframe_interval_s (dropped as late).
  bool TooCloseToNewestKeyframe(const lidar::LidarSweep& sweep) const;
  void ProcessCoveredSweeps();
  // One window update for a covered sweep (steps 1-5 above).
  void Update(lidar::LidarSweep sweep);
  void AddKeyframe(lidar::LidarSweep sweep);
  // Wheel and GNSS factors for the buffered samples in (from, t_end_ns], attached to `from`.
  void AttachIntervalMeasurements(WindowKeyframe* from, int64_t t_end_ns);
  void RelinearizeImuFactors();
  // Step 3: refreshes the plane maps that moved and makes the pairing tries that are missing
  // or stale ("Reuse between updates").
  void AssociatePoints();
  // The window problem: keyframes, calibration blocks, IMU/wheel/GNSS factors, priors and the
  // keyframes' point groups. The point groups are linearized afresh, or, given their motions
  // (PointGroupMotions, in its order; a later pass of an update), only those that moved by
  // more than relinearization_tolerance_m since their linearization (Eq. SW12).
  std::unique_ptr<ProblemBuild> BuildProblem(const std::vector<double>* group_motions = nullptr);
  // Step 4; replaces *build with each later pass's problem, the point groups that moved
  // relinearized where the previous pass ended (Eq. SW7, SW12).
  void Solve(std::unique_ptr<ProblemBuild>* build);
  // Per point group of the window, in the order of the keyframes and their groups: how far
  // its two sweeps moved relative to each other since its linearization (Eq. SW12; infinite
  // when it has none).
  std::vector<double> PointGroupMotions() const;
  // Sum of the squared point-to-plane distances (m^2, without the loss) at the current
  // estimate of the point groups of the window (only those that pair a sweep with the oldest
  // keyframe's, either way round, if so asked).
  double SquaredPointDistances(bool oldest_only) const;
  std::unique_ptr<MarginalizationPrior> MarginalizeOldest(ProblemBuild* build);
  // With options_.smoothing: keeps the oldest keyframe's conditional (Eq. M4) for
  // SmoothedTrajectory().
  void RecordSmoothingStep(MarginalConditional conditional);
  void DropOldest(std::unique_ptr<MarginalizationPrior> prior);
  void TrimImuBuffer();

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

  sensors::ImuSamples imu_;  // from the oldest window keyframe on
  std::deque<sensors::WheelSample> wheel_;
  std::deque<GnssPosition> gnss_;
  std::deque<lidar::LidarSweep> pending_sweeps_;
  int64_t newest_wheel_ns_;
  int64_t newest_gnss_ns_;
  int64_t newest_sweep_ns_;

  std::deque<std::unique_ptr<WindowKeyframe>> window_;
  // The pairing's try buffer of the keyframe last marginalized (a megabyte at thousands of
  // points), which the next keyframe takes over instead of allocating it afresh.
  std::vector<int> spare_tried_at_;
  int next_keyframe_id_ = 0;
  std::vector<SlidingWindowState> marginalized_;
  std::vector<SmoothingStep> smoothing_;  // one per marginalized_, with options_.smoothing
  // Prior of the marginalized keyframes; replaced by every marginalization.
  std::unique_ptr<MarginalizationPrior> prior_;
  std::vector<internal::AttachedFactor> calibration_priors_;
  // The solver's dense buffers, kept from update to update.
  std::unique_ptr<internal::WindowSolverWorkspace> solver_workspace_;
  // The point groups' storage and the pairing's buffers, kept for reuse.
  class TermsPool;
  std::unique_ptr<TermsPool> terms_pool_;

  SlidingWindowCounters counters_;
  SlidingWindowUpdateTiming timing_;
  // q_I_L after each of the last window_size updates (the association gate, Eq. SW14).
  std::deque<Eigen::Quaterniond> recent_q_I_L_;
  int last_associated_points_ = 0;
  // Squared distances of the groups the last update's marginalization dropped; the RMS once
  // evaluated.
  double dropped_point_squared_m2_ = 0.0;
  mutable std::optional<double> last_point_rms_m_ = 0.0;
};

}  // namespace estimation
}  // namespace autocal
