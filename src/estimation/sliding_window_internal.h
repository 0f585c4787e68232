#pragma once

// Private state of the sliding window shared by its source files (docs/sliding_window.md).

#include <memory>
#include <optional>
#include <vector>

#include <ceres/ceres.h>

#include "autocal/estimation/sliding_window.h"
#include "autocal/lidar/point_cloud.h"
#include "autocal/sensors/imu_preintegration.h"
#include "estimation/sliding_window_factors.h"

namespace autocal {
namespace estimation {

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
};

// One window problem and the cost functions it alone uses (the problem owns nothing).
struct SlidingWindowEstimator::ProblemBuild {
  std::vector<std::unique_ptr<ceres::CostFunction>> owned;
  std::vector<ceres::ResidualBlockId> point_blocks;
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
