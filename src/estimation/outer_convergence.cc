#include "estimation/outer_convergence.h"

#include <cmath>

#include "autocal/common/units.h"
#include "autocal/geometry/so3.h"

namespace autocal {
namespace estimation {
namespace internal {

OuterStep StepBetween(const sensors::Calibration& before, const sensors::Calibration& after) {
  return {geometry::AngularDistance(before.q_I_L, after.q_I_L) * kRadToDeg,
          (before.p_I_L - after.p_I_L).norm(),
          std::abs(before.time_offset_lidar_imu_s - after.time_offset_lidar_imu_s)};
}

bool StepConverged(double step, double previous, double threshold) {
  if (step < threshold) return true;
  if (!(step < previous)) return false;
  const double rate = step / previous;
  return step * rate / (1.0 - rate) < threshold;
}

bool OuterLoopConverged(const LidarInertialBatchOptions& options, const OuterStep& step,
                        const std::optional<OuterStep>& previous_step) {
  const OuterStep previous = previous_step.value_or(OuterStep());
  return StepConverged(step.rotation_deg, previous.rotation_deg, options.converged_rotation_deg) &&
         StepConverged(step.translation_m, previous.translation_m,
                       options.converged_translation_m) &&
         StepConverged(step.time_offset_s, previous.time_offset_s, options.converged_time_offset_s);
}

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
