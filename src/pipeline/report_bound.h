#pragma once

// The report's section on the information bound (docs/report.md, "Against the Cramer-Rao
// bound"): per estimated direction its sigma against the bound at the truth, when the run
// computed one (a simulated log).

#include <string>

#include "autocal/pipeline/offline_calibration.h"

namespace autocal {
namespace pipeline {

// "" without result.bound.
std::string BoundSection(const OfflineCalibrationResult& result);

}  // namespace pipeline
}  // namespace autocal
