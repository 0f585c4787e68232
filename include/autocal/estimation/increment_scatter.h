#pragma once

// Whether a streaming estimate of the calibration moves over the log as its covariance says it
// should, and its covariance widened where it moves more (docs/sliding_window.md, Eq. W9). The
// posterior mean of a constant is a martingale: between two times its step has the covariance
// by which the posterior covariance shrank, C_a - C_b, and steps over disjoint spans are
// uncorrelated. Rows whose errors last for stretches of the drive, or noise larger than the
// model states, make the steps scatter more widely than that; by the same factor, in a
// direction, the final error does. The window cannot keep its marginalized stretches' rows
// (what the batch's Eq. C8 reads), but its estimate and covariance at a few times of the log
// carry the same evidence.

#include <Eigen/Core>
#include <string>
#include <vector>

#include "autocal/estimation/sliding_window.h"
#include "autocal/sensors/calibration.h"

namespace autocal {
namespace estimation {

// The estimate of the calibration at one time of the log and its covariance then.
struct CalibrationCheckpoint {
  sensors::Calibration value;
  CalibrationCovariance covariance;
};

// Per row of the last checkpoint's covariance: the steps between consecutive checkpoints,
// each over its predicted sigma, z_j = d_j / sqrt(C_j - C_j+1), and their typical square
// against chance's. A step is left out whose predicted variance is below a quarter of an even
// share of the final one, C_n / (4 n) for n steps (under a posterior, every step predicts at
// least about C_n / n when the data inform the direction evenly): its span hardly informs the
// direction, and what moves an estimate there is its re-solving, not new data. The median of
// the z_j^2 (the lower one for an even count) resists a few steps that are not noise, such as
// the first ones while the estimate settles from its start.
struct IncrementScatter {
  struct Direction {
    std::string block;  // the block's name in the covariance
    int row = 0;        // the row in the last checkpoint's covariance
    int steps = 0;      // steps judged (predicted variance above the floor)
    // The median z_j^2 over that of the same order statistic of as many chi^2(1) draws: the
    // steps' variance over the predicted one (1 when the covariance is right).
    double ratio = 0.0;
    // The median z_j^2 is beyond what chi^2(1) draws exceed with probability `significance`.
    bool exceeds = false;
  };
  std::vector<Direction> directions;
};

// Throws autocal::Error unless significance lies in (0, 1). Fewer than two checkpoints give
// no directions.
IncrementScatter ScatterOfIncrements(const std::vector<CalibrationCheckpoint>& checkpoints,
                                     double significance);

// `covariance` (the last checkpoint's) scaled as D C D, D_rr = sqrt(ratio) in the directions
// whose steps exceed chance (their correlations kept), no variance past max_variance (per
// row; never narrower than it was). *widened_directions receives those directions with their
// sigma factor, largest first (may be null).
struct WidenedDirection {
  IncrementScatter::Direction direction;
  double sigma_factor = 1.0;
};
CalibrationCovariance WidenedForIncrements(const CalibrationCovariance& covariance,
                                           const IncrementScatter& scatter,
                                           const Eigen::VectorXd& max_variance,
                                           std::vector<WidenedDirection>* widened_directions);

namespace internal {

// The q at which the m-th smallest of n independent chi^2(1) draws exceeds q with probability
// `tail` (0 < tail < 1, 1 <= m <= n).
double OrderStatisticQuantile(int m, int n, double tail);

}  // namespace internal

}  // namespace estimation
}  // namespace autocal
