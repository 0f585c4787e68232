#pragma once

// When the batch's outer loop (estimation/lidar_inertial_batch.h) stops (docs/estimation.md,
// Eq. P12). Each outer iteration re-associates the points and solves again: a fixed-point
// iteration, whose steps near the solution shrink by a constant rate while the level and the
// points' sigma stay the same. Its sum from step k on is a geometric series: a step s_k that
// shrank from s_{k-1} at the rate r = s_k / s_{k-1} < 1 leaves s_k r / (1 - r) to come.

#include <optional>

#include "autocal/estimation/lidar_inertial_batch.h"
#include "autocal/sensors/calibration.h"

namespace autocal {
namespace estimation {
namespace internal {

// How far an outer iteration moved the LiDAR-IMU extrinsic and time offset.
struct OuterStep {
  double rotation_deg = 0.0;
  double translation_m = 0.0;
  double time_offset_s = 0.0;
};

OuterStep StepBetween(const sensors::Calibration& before, const sensors::Calibration& after);

// Whether a quantity that moved by `step` has converged to `threshold`: the step is below it,
// or it shrank from `previous` (0: no step of the same map before it) at a rate r < 1 and the
// moves still to come, step r / (1 - r), are below it.
bool StepConverged(double step, double previous, double threshold);

// StepConverged for each of the extrinsic's rotation and translation and the offset, against
// options' converged_rotation_deg, converged_translation_m and converged_time_offset_s;
// `previous`: the step before, when it was of the same map (the same level and points' sigma).
bool OuterLoopConverged(const LidarInertialBatchOptions& options, const OuterStep& step,
                        const std::optional<OuterStep>& previous);

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
