#pragma once

// The offline calibration's residuals by sensor (IMU, wheel, GNSS, planar rotation): their
// whitened rows before any robust loss, the factors the loss down-weighted, and the
// statistics calibration.yaml and the summary give of them.

#include <ceres/ceres.h>

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "autocal/estimation/calibration_observability.h"
#include "autocal/factors/loss.h"
#include "autocal/pipeline/offline_calibration.h"

namespace autocal {
namespace pipeline {

// Statistics of one sensor's whitened rows (no robust loss) for calibration.yaml's residuals:
// "rows" and "whitened_rms" (all rows); with alike_rows (rows of one kind, as GNSS's east,
// north and up; not the IMU's or the wheels', whose kinds differ in scale) also
// "whitened_robust_sigma" (1.4826 times the median |r|: about 1 when the noise is as stated,
// whatever the outliers), "outlier_rows" (beyond kOutlierRobustSigmas robust sigmas) and
// "whitened_rms_without_outliers". A few multipath fixes can carry nearly all of the plain RMS
// (14 GNSS rows made it 17 on a simulated urban drive whose other rows have 0.99).
constexpr double kOutlierRobustSigmas = 5.0;
std::map<std::string, double> WhitenedStatistics(const std::vector<double>& rows, bool alike_rows);

// Every residual block of `problem` by where its information comes from, for the error budget:
// "lidar" (the point-to-plane factors), "imu", "wheel", "gnss", "planar_rotation", and
// "priors" (every other factor: the blocks' priors, the first pose or the bias priors and
// gauge of a run without the LiDAR), the empty ones left out. Each with its share ratio
// (Eq. C8): the point groups' from their own distances (the points' sigma is measured from
// them, Eq. P10, and wrong pairs give them a heavier tail than a Gaussian's), every other
// block's as its loss gives it for rows N(0, I) at their stated sigma.
std::vector<estimation::ResidualSource> ResidualSources(ceres::Problem* problem);

// The point groups (factors::PointToSweepPlaneGroupFactor) among `ids`, appended to `groups`
// when given, with their whitened distances at the problem's values added to the ratio of
// their loss (one loss for every point group of a solve); nullopt when there are none.
std::optional<factors::SandwichRatio> PointGroupDistances(
    ceres::Problem* problem, const std::vector<ceres::ResidualBlockId>& ids,
    std::vector<ceres::ResidualBlockId>* groups = nullptr);

// Whitened residual rows (no robust loss) of the IMU, wheel and GNSS factors in `problem`,
// by sensor, at the current parameter values.
std::map<std::string, std::vector<double>> WhitenedResidualsBySensor(ceres::Problem* problem);

// After the solve, for each sensor in `problem` at the current values: SensorResiduals::after
// (the rows WhitenedResidualsBySensor gives, in the same order), factors, factors_downweighted
// and rms_not_downweighted, from one evaluation of each factor. A factor counts as
// down-weighted by factors::DownweightedByLoss at its squared whitened norm.
void RecordResidualsAfterSolve(ceres::Problem* problem,
                               std::map<std::string, SensorResiduals>* residuals);

}  // namespace pipeline
}  // namespace autocal
