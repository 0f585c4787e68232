#pragma once

// Batch LiDAR-inertial refinement over a whole log (docs/estimation.md, "Batch
// LiDAR-inertial solve"): one keyframe per LiDAR sweep, IMU preintegration factors between
// consecutive keyframes, point-to-plane factors from every sweep against a plane map built
// from all sweeps, and the LiDAR-IMU extrinsic and time offset shared by all of them.
// An outer loop re-propagates the sweeps with the current estimate, rebuilds the map,
// re-associates the points and solves again (ICP style) until the calibration settles. The
// point selection, deskew and partner order are the sliding window's (PairingOptions).
//
// This is the solver core: it starts from given keyframe states and calibration (from an
// initializer or a previous run) and refines them in place.

#include <ceres/ceres.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "autocal/common/time.h"
#include "autocal/estimation/estimated_blocks.h"
#include "autocal/estimation/imu_motion_table.h"
#include "autocal/estimation/keyframe.h"
#include "autocal/estimation/pairing_options.h"
#include "autocal/factors/loss.h"
#include "autocal/lidar/point_cloud.h"
#include "autocal/sensors/calibration.h"
#include "autocal/sensors/measurements.h"
#include "autocal/sensors/sensor_config.h"

namespace autocal {
namespace estimation {

struct LidarInertialBatchProgress {
  int iteration = 0;  // 1-based outer iteration just finished
  int max_iterations = 0;
  double cost = 0.0;       // final cost of its solve
  double elapsed_s = 0.0;  // wall time since the solve began
  int associated_points = 0;
};

struct LidarInertialBatchOptions {
  sensors::ImuNoise imu_noise;
  double gravity_m_s2 = 9.80665;
  // Residual and map points, partners and the outlier gate (shared with the sliding window).
  PairingOptions pairing = BatchPairingDefaults();
  // The planes attributed to sweep j are fitted to the points of sweeps j - n ... j + n.
  int map_neighbor_sweeps = 0;
  // Robust loss on point residuals, scale in units of sigma.
  factors::LossOptions point_loss{factors::RobustLoss::kCauchy, 2.0};
  // The first iteration accepts planes 2^steps times thicker and points that much farther and
  // noisier, so that a calibration still far off finds associations; each later one halves
  // that at least, and goes straight to the level its distances need (docs/estimation.md,
  // "Coarse to fine", Eq. P11).
  int coarse_to_fine_steps = 3;
  // When positive, the starting q_I_L is one no motion checked (the nominal value, with
  // keyframes that no LiDAR motion placed): before the first iteration, rotations within this
  // many degrees of it about the two axes across the direction of travel are scored by the
  // points of consecutive keyframes that find a plane, and the solve starts from the best
  // (docs/estimation.md, "A rotation no motion checked", Eq. P13). 0: the solve starts from
  // q_I_L as given.
  double starting_rotation_search_deg = 0.0;
  // The points' sigma after the coarse iterations: the RMS distance of the previous
  // iteration's points within the gate, the variance of unit weight of the LiDAR residuals
  // (docs/estimation.md, "The points' sigma"); pairing.point_sigma_m is the starting value.
  // false: pairing.point_sigma_m throughout.
  bool point_sigma_from_residuals = true;
  // The fine iterations accept a local plane only when no neighbour lies farther from it than
  // this many of the points' sigma (and pairing.plane_map.max_plane_thickness_m): a thicker
  // neighbourhood spans an edge or a curved surface, whose plane biases the distances of the
  // points paired with it (docs/estimation.md, Eq. P10b). 0: the configured gate alone.
  double plane_thickness_sigmas = 3.5;
  int outer_iterations = 8;
  int solver_iterations = 15;
  int num_threads = 1;
  LidarEstimatedBlocks estimate;  // the others are held at their starting value
  // Axes of p_I_L (IMU frame) held at their starting value, e.g. those the motion does not
  // excite (z under planar driving): the estimate keeps the prior there instead of noise.
  Eigen::Matrix<bool, 3, 1> hold_p_I_L_axes = Eigen::Matrix<bool, 3, 1>::Constant(false);
  // After the last solve, the covariance of the estimated calibration blocks.
  bool compute_covariance = true;
  // Adds other factors (wheel, GNSS, priors) to every outer iteration's problem, after the
  // keyframe and LiDAR-IMU calibration blocks are in it; may be empty. Quaternion blocks it
  // adds need a manifold that outlives the solve (the problem does not own manifolds).
  std::function<void(ceres::Problem*, std::vector<Keyframe>*, sensors::Calibration*)> add_factors;
  // Holds the first keyframe's position and yaw, which fixes the gauge (roll and pitch stay
  // free: gravity determines them). Factors that fix it themselves (GNSS) replace this.
  bool hold_first_pose = true;
  // Called with the final problem after the last solve (e.g. for the covariance of blocks
  // added by add_factors); may be empty.
  std::function<void(ceres::Problem*)> inspect_final_problem;
  // Called after every outer iteration (for progress displays); may be empty.
  std::function<void(const LidarInertialBatchProgress&)> progress;
  // Stop the outer loop when an iteration moves the extrinsic less than these, or when the
  // moves still to come, from the rate its steps shrink at, are less (Eq. P12,
  // docs/estimation.md): a tenth of the accuracy the calibration is held to, or less (an axis
  // the drive does not excite wanders by millimetres between iterations and must not keep the
  // loop going).
  double converged_rotation_deg = 2e-3;
  double converged_translation_m = 1e-3;
  double converged_time_offset_s = 1e-5;
  // ... and the points' sigma (point_sigma_from_residuals) moves by less than this fraction.
  double converged_point_sigma_ratio = 0.05;
};

// The search for the starting rotation (LidarInertialBatchOptions::starting_rotation_search_deg).
struct StartingRotationSearch {
  // false: off, no scored pair (the car stood, or the IMU does not cover the sweeps), or the
  // keyframes lie so close that one step exceeds the range.
  bool searched = false;
  double step_deg = 0.0;    // the grid's step
  int candidates = 0;       // rotations scored
  int paired_at_start = 0;  // scored points that found a plane at the given rotation
  int paired_at_best = 0;   // ... at the rotation the solve started from
  Eigen::Quaterniond q_I_L_given = Eigen::Quaterniond::Identity();
  Eigen::Quaterniond q_I_L_start = Eigen::Quaterniond::Identity();  // the best
};

struct LidarInertialBatchReport {
  StartingRotationSearch rotation_search;
  int outer_iterations = 0;
  // Whether the outer loop ended by its criteria (the converged_* settings, on the fine level)
  // rather than at options.outer_iterations.
  bool converged = false;
  int associated_points = 0;  // in the last iteration
  double final_cost = 0.0;
  double point_rms_m = 0.0;    // RMS point-to-plane distance of the last iteration
  double point_sigma_m = 0.0;  // the points' sigma in the last iteration's factors
  // The last iteration's points the robust loss down-weighted (weight rho'(s) below one half at
  // s = (distance / sigma)^2, as for the other sensors' factors) and the others' RMS distance.
  int points_downweighted_by_loss = 0;
  double point_rms_not_downweighted_m = 0.0;
  std::vector<sensors::Calibration> calibration_per_iteration;
  // Each iteration's coarse level: planes 2^level times thicker, points that much farther and
  // noisier (0: fine).
  std::vector<int> coarse_level_per_iteration;
  // Signed point-to-plane distances (m, no robust loss) at the start of the first iteration
  // and after the last solve, for residual statistics and histograms.
  std::vector<double> initial_point_residuals_m;
  std::vector<double> final_point_residuals_m;
  std::string termination;  // Ceres' message of the last solve
  // Wall time spent propagating, building maps, associating and building the problems, and
  // in Ceres, summed over the outer iterations.
  double seconds_association = 0.0;
  double seconds_solver = 0.0;
  // Covariance of the LiDAR-IMU calibration (when options.compute_covariance and Ceres could
  // compute it: held or constant blocks have zero rows): rotation about the right
  // perturbation of q_I_L (rad^2), p_I_L (m^2) and the offset (s^2), in that order.
  bool covariance_ok = false;
  Eigen::Matrix<double, 7, 7> covariance = Eigen::Matrix<double, 7, 7>::Zero();
};

// A sweep reduced to what the batch reads of it: its residual and map points (pairing's
// selection, in their order in the sweep) with their times, and the times of its first and last
// points.
// Points and times are held in single precision, as sweep files (PLY) and LiDAR drivers give
// them, so that for them the reduction is exact; a long log's sweeps are held this way, under
// a quarter of their size (0.22 of 0.97 MB for 32 beams), instead of whole.
struct SelectedSweep {
  int64_t t_ns = 0;
  SweepSpan span;                    // the whole sweep's, not only the selected points'
  Eigen::Matrix3Xf points;           // in L
  Eigen::VectorXf time_s;            // after t_ns
  std::vector<int> residual_points;  // indices into points
  std::vector<int> map_points;       // indices into points

  Eigen::Vector3d point(int i) const { return points.col(i).cast<double>(); }
  // The IMU interval a motion table of the sweep from its keyframe at keyframe_ns covers at
  // LiDAR-IMU time offset offset_s: its points, its reference instant (point time 0) and the
  // keyframe.
  ImuInterval TableInterval(double offset_s, int64_t keyframe_ns) const {
    return MotionTableInterval(t_ns, span, offset_s, keyframe_ns);
  }
  double time(int i) const { return static_cast<double>(time_s(i)); }
};
// Throws autocal::Error for a sweep without per-point time.
SelectedSweep SelectForBatch(const lidar::LidarSweep& sweep, const PairingOptions& pairing);

// Refines `keyframes` (one per sweep, in sweep order) and the LiDAR-IMU part of
// `calibration` (q_I_L, p_I_L, time_offset_lidar_imu_s, and whatever blocks the factors of
// options.add_factors touch) in place. Unless options.hold_first_pose is off, the first
// keyframe's position and yaw fix the gauge (they are unobservable from IMU and LiDAR alone)
// and are held.
// Throws autocal::Error when the inputs do not fit (sizes, IMU coverage).
LidarInertialBatchReport SolveLidarInertialBatch(const sensors::ImuSamples& imu,
                                                 const std::vector<lidar::LidarSweep>& sweeps,
                                                 std::vector<Keyframe>* keyframes,
                                                 sensors::Calibration* calibration,
                                                 const LidarInertialBatchOptions& options = {});
// The same on sweeps already reduced by SelectForBatch with options.pairing (the results are
// identical).
LidarInertialBatchReport SolveLidarInertialBatch(const sensors::ImuSamples& imu,
                                                 const std::vector<SelectedSweep>& sweeps,
                                                 std::vector<Keyframe>* keyframes,
                                                 sensors::Calibration* calibration,
                                                 const LidarInertialBatchOptions& options = {});

}  // namespace estimation
}  // namespace autocal
