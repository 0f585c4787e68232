#pragma once

// Private state of the sliding window shared by its source files (docs/sliding_window.md).

#include <memory>
#include <optional>
#include <vector>

#include <ceres/ceres.h>

#include "autocal/estimation/plane_map.h"
#include "autocal/estimation/sliding_window.h"
#include "autocal/factors/point_to_sweep_plane_group_factor.h"
#include "autocal/geometry/se3.h"
#include "autocal/lidar/point_cloud.h"
#include "autocal/sensors/imu_preintegration.h"
#include "estimation/sliding_window_factors.h"

namespace autocal {
namespace estimation {

namespace internal {

// The residual points of one keyframe paired with planes of one partner keyframe's sweep: one
// residual block (Eq. P9) over both keyframes' q, p, v and q_I_L, p_I_L, time offset.
struct SweepPointGroup {
  int partner_id = 0;  // the partner keyframe's id
  // T_Lj_Lk between the two sweeps' reference instants when the points were paired.
  geometry::Pose3d T_Lj_Lk;
  std::unique_ptr<factors::PointToSweepPlaneGroupFactor> factor;
  // The block the solver sees: `factor` compressed (Eq. SW5) when it has more rows than that.
  std::unique_ptr<CompressedPointGroup> compressed;
  std::vector<double*> parameters;

  ceres::CostFunction* solver_cost() const {
    return compressed ? static_cast<ceres::CostFunction*>(compressed.get()) : factor.get();
  }
};

}  // namespace internal

struct SlidingWindowEstimator::WindowKeyframe {
  int id = 0;
  SlidingWindowState state;
  // The sweep that made this keyframe (none for the initial keyframe) and its chosen points.
  std::optional<lidar::LidarSweep> sweep;
  double sweep_duration_s = 0.0;
  std::vector<int> residual_points;
  std::vector<int> map_points;
  // Preintegration from the previous keyframe (none for the oldest in the window).
  std::unique_ptr<sensors::ImuPreintegration> imu_from_previous;
  // Factors on this keyframe alone (or with calibration blocks): the initial-state prior,
  // wheel and GNSS samples of the interval that starts here.
  std::vector<internal::AttachedFactor> factors;
  // The sweep's plane map in its LiDAR frame at the reference instant (point time 0), and the
  // sweep's motion in that frame to its last point, T_L0_L(tau_max), it was deskewed with
  // (docs/sliding_window.md, "Reuse between updates", Eq. SW4).
  std::unique_ptr<PlaneMap> plane_map;
  geometry::Pose3d map_deskew_end;
  double map_max_range_m = 0.0;
  // This keyframe's residual points paired with other window sweeps, one group per partner,
  // the range of its farthest residual point, and whether they were paired yet.
  std::vector<internal::SweepPointGroup> point_groups;
  double residual_max_range_m = 0.0;
  bool paired = false;
  int newest_id_at_pairing = -1;  // the newest window keyframe then
  bool lost_partner = false;      // a partner was marginalized since
};

// One window problem and the cost functions it alone uses (the problem owns nothing).
struct SlidingWindowEstimator::ProblemBuild {
  std::vector<std::unique_ptr<ceres::CostFunction>> owned;
  std::unique_ptr<ceres::Problem> problem;
};

namespace internal {

// The five state blocks of a keyframe, in the order the IMU factor and the priors take them.
inline std::vector<double*> StateBlocks(SlidingWindowState* s) {
  return {s->q_W_I.coeffs().data(), s->p_W_I.data(), s->v_W_I.data(), s->b_g.data(),
          s->b_a.data()};
}

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
