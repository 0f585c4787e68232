#pragma once

// The calibration report (report.html): one self-contained page, viewable offline, with the
// summary table (values, sigma, observability), LiDAR residual histograms before and after
// the solve, the trajectory seen from above, the time-offset correlation curve, the
// convergence of each calibration block and the warnings. Charts are inline SVG.

#include <string>

#include "autocal/pipeline/offline_calibration.h"

namespace autocal {
namespace pipeline {

std::string CalibrationReportHtml(const OfflineCalibrationResult& result);

}  // namespace pipeline
}  // namespace autocal
