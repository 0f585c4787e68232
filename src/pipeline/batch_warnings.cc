#include "batch_warnings.h"

#include <cmath>
#include <iomanip>
#include <sstream>

#include "autocal/common/format.h"
#include "autocal/common/units.h"
#include "autocal/geometry/so3.h"

namespace autocal {
namespace pipeline {

std::string RotationSearchWarning(const estimation::StartingRotationSearch& search) {
  const double moved_deg =
      geometry::AngularDistance(search.q_I_L_given, search.q_I_L_start) * kRadToDeg;
  if (!search.searched || moved_deg == 0.0) return "";
  return "the LiDAR rotation's nominal value, which no turn of the drive checked, paired " +
         std::to_string(search.paired_at_start) + " points of consecutive keyframes; " +
         FormatFixed(moved_deg, 2) + " deg from it " + std::to_string(search.paired_at_best) +
         " paired, and the solve started there (" + std::to_string(search.candidates) +
         " rotations in steps of " + FormatFixed(search.step_deg, 2) +
         " deg): the nominal rotation in sensors.yaml may be that far off";
}

std::string StillMovingWarning(const estimation::LidarInertialBatchReport& batch,
                               const sensors::Calibration& start,
                               const std::vector<estimation::EstimatedBlock>& blocks,
                               const estimation::BlockObservability& observability) {
  const std::vector<sensors::Calibration>& steps = batch.calibration_per_iteration;
  if (batch.converged || steps.empty() || observability.sigma.size() != blocks.size()) return "";
  sensors::Calibration before = steps.size() >= 2 ? steps[steps.size() - 2] : start;
  sensors::Calibration after = steps.back();
  std::string moving;
  for (size_t b = 0; b < blocks.size(); ++b) {
    const estimation::EstimatedBlock& block = blocks[b];
    // The change in the block's tangent (a rotation: about its own axes, as its sigma).
    const Eigen::VectorXd change =
        estimation::BlockMinus(block, estimation::BlockOf(block.id, &after).data,
                               estimation::BlockOf(block.id, &before).data);
    for (int d = 0; d < block.size; ++d) {
      const double sigma = observability.sigma[b](d);
      const double moved = std::abs(change(d));
      if (observability.held[b][static_cast<size_t>(d)] || !(sigma > 0.0) ||
          moved <= kStillMovingSigmaFraction * sigma) {
        continue;
      }
      std::ostringstream by;
      by << std::setprecision(3) << moved * block.display_scale << ' ' << block.display_unit;
      moving += (moving.empty() ? "" : ", ") + block.direction_names[static_cast<size_t>(d)] +
                " by " + by.str() + " (" + FormatFixed(moved / sigma, 2) + " sigma)";
    }
  }
  if (moving.empty()) return "";
  return "the solve stopped at its " + std::to_string(batch.outer_iterations) +
         " outer iterations (solver.outer_iterations) with its last one still moving " + moving +
         ": the estimate may lie short of the solution; raise solver.outer_iterations in the "
         "problem file";
}

}  // namespace pipeline
}  // namespace autocal
