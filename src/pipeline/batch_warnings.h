#pragma once

// What the offline calibration says of how its batch solve went: where the search for a
// nominal LiDAR rotation started it (docs/estimation.md, Eq. P13), and which directions its
// last outer iteration still moved when it stopped at solver.outer_iterations
// (problems/README.md, "Outer iterations").

#include <string>
#include <vector>

#include "autocal/estimation/calibration_observability.h"
#include "autocal/estimation/lidar_inertial_batch.h"
#include "autocal/sensors/calibration.h"

namespace autocal {
namespace pipeline {

// Where the batch's search put a nominal starting LiDAR rotation, and from how many paired
// points; empty when the search did not run or kept the nominal value.
std::string RotationSearchWarning(const estimation::StartingRotationSearch& search);

// The outer loop stops at solver.outer_iterations whether or not it converged. A direction
// that is not held and that the last iteration still moved by more than this fraction of its
// sigma may lie short of the solution: on a drive that determines it weakly, each iteration's
// associations move it a little further (docs/calibration.md, "Highway").
constexpr double kStillMovingSigmaFraction = 0.05;

// The warning that names those directions of `blocks` (their sigma and held flags in
// `observability`, from the final problem) and by how much they moved, from the batch's
// second-to-last iteration, or from `start` (the calibration the batch started from) after a
// single one; empty when the loop converged, nothing moved that much, or no sigma is known.
std::string StillMovingWarning(const estimation::LidarInertialBatchReport& batch,
                               const sensors::Calibration& start,
                               const std::vector<estimation::EstimatedBlock>& blocks,
                               const estimation::BlockObservability& observability);

}  // namespace pipeline
}  // namespace autocal
