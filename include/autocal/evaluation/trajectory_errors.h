#pragma once

// Absolute trajectory error (ATE) of an estimated trajectory T_W_I against the truth, after a
// 4-DoF alignment (yaw about the gravity axis z, and a translation): gravity makes roll and
// pitch observable, so an estimator may differ from the truth only by those four degrees of
// freedom (docs/evaluation.md, "Trajectory").

#include <Eigen/Core>

#include "autocal/io/dataset.h"

namespace autocal {
namespace evaluation {

struct TrajectoryErrorOptions {
  // An estimated pose between two truth samples is compared with the truth interpolated
  // between them (linear in position, slerp in rotation) when they are at most this far
  // apart; a pose outside the truth's span or in a wider gap is left out (counted).
  double max_interpolation_gap_s = 0.1;
  // Below this RMS horizontal distance of the matched positions from their centroid, the
  // positions cannot fix the yaw; it is then taken from the orientations (circular mean of
  // the yaw of R_true R_est^T).
  double min_horizontal_spread_m = 1.0;
};

// p_aligned = Rz(yaw_rad) p_est + translation_m, R_aligned = Rz(yaw_rad) R_est.
struct Alignment4Dof {
  double yaw_rad = 0.0;
  Eigen::Vector3d translation_m = Eigen::Vector3d::Zero();
  bool yaw_from_orientation = false;  // the positions had too little horizontal spread
};

struct TrajectoryErrors {
  int matched_poses = 0;    // compared with the truth
  int exact_matches = 0;    // of those, stamps found in the truth (no interpolation)
  int unmatched_poses = 0;  // outside the truth's span or in a gap
  Alignment4Dof alignment;
  double ate_translation_rmse_m = 0.0;  // sqrt(mean |p_aligned − p_true|²)
  double ate_rotation_rmse_deg = 0.0;   // sqrt(mean angle(R_true^T R_aligned)²)
  // sqrt(mean tilt²), the tilt the angle between the true and the estimated up direction in the
  // body (R_true^T z against R_est^T z): the roll and pitch error, which no yaw alignment moves.
  double tilt_rmse_deg = 0.0;
  double max_translation_error_m = 0.0;
  double max_rotation_error_deg = 0.0;
};

// The truth at `t_ns`: the sample with that stamp (*exact true), else the interpolation of its
// neighbours (linear in position and velocity, slerp in rotation) when they are at most
// `max_gap_ns` apart. Returns false outside the truth's span or in a gap.
bool TruthAt(const io::Trajectory& truth, int64_t t_ns, int64_t max_gap_ns,
             io::TrajectorySample* sample, bool* exact);

// Least-squares 4-DoF alignment of `estimate` onto `truth` (equal lengths, matched pairs).
// Throws autocal::Error when the lists are empty or differ in length.
Alignment4Dof AlignYawAndTranslation(const io::Trajectory& estimate, const io::Trajectory& truth,
                                     double min_horizontal_spread_m = 1.0);

// Matches every estimated pose to the truth by stamp (exactly, else by interpolation), aligns
// and measures. Both trajectories must have strictly increasing stamps. Throws autocal::Error
// when no estimated pose can be matched.
TrajectoryErrors CompareTrajectory(const io::Trajectory& estimate, const io::Trajectory& truth,
                                   const TrajectoryErrorOptions& options = {});

}  // namespace evaluation
}  // namespace autocal
