#pragma once

// The calibration report (report.html, docs/report.md): one self-contained page, viewable
// offline (inline CSS and SVG, no script, no external resource), with
//   - the summary table (value, sigma, nominal, observability of every reported block), the
//     solve in one sentence and one line per sensor ("LiDAR: not used" when it took no part);
//   - the warnings;
//   - residual histograms before and after the solve, one per sensor with data: the LiDAR's
//     point-to-plane distances in metres, and the whitened rows of the IMU, wheel and GNSS
//     factors in units of sigma over +-5 sigma against a standard normal, each with its RMS
//     and the share beyond the range;
//   - the convergence of every estimated block (change from the first outer iteration in deg,
//     cm, ms, % or mm), or a sentence when fewer than two iterations were recorded;
//   - the initializer's time-offset correlation curve, when the LiDAR took part;
//   - the trajectory from above, against the GNSS fixes when GNSS took part.
// Sections without data are left out; text is HTML-escaped and non-finite numbers print
// as "–", whatever the result holds.

#include <string>

#include "autocal/pipeline/offline_calibration.h"

namespace autocal {
namespace pipeline {

std::string CalibrationReportHtml(const OfflineCalibrationResult& result);

}  // namespace pipeline
}  // namespace autocal
