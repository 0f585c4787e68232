#pragma once

// Whether each sensor's rows scatter over the log as their noise model says, and the
// calibration's covariance widened where they do not (docs/calibration.md, Eq. C8). The
// posterior covariance H^-1 holds when every row's noise is independent at its stated sigma;
// on a real log a controller's odometry slips for seconds on one stretch of terrain, a
// receiver's fixes drift together, and the stated sigmas are placeholders. The log is cut into
// stretches; each stretch's share of the estimate's error, U_b = X^T J_b^T r_b (X: H^-1's
// columns at the calibration), should scatter as its noise model gives. Where a source's
// shares scatter more than chance allows, the estimate's covariance is the sandwich
// H^-1 S H^-1 with that source's part of S measured from the stretches.

#include <Eigen/Core>
#include <string>
#include <vector>

namespace autocal {
namespace estimation {

struct BlockCovariance;

// Per source, over its stretches b (the calibration's stacked coordinates), with T = sum_b U_b:
//   observed = sum_b U_b U_b^T - T T^T / B, the shares' scatter about their mean;
//   expected = its expectation were the source's rows independent and as its noise model says,
//              at the fitted residuals: share_ratio (sum_b E_b - (model - Y^T H^-1 Y) / B),
//              where E_b = V_b - Y_b^T H^-1 Y_b, V_b = X^T J_b^T J_b X, Y_b = J_b^T J_b X and
//              Y = sum_b Y_b (the solve fits part of each stretch's noise away), and
//              ResidualSource::share_ratio what a robust loss makes the shares vary by;
//   model    = sum_b V_b, the source's part of the covariance H^-1 (whose diagonal is
//              `variance`);
//   degrees_of_freedom = (sum_b E_b,cc)^2 / sum_b E_b,cc^2 - 1 per coordinate (Satterthwaite's,
//              less the one the mean takes; at least 1): a drive whose turns fall in two
//              stretches has about one.
// The shares are taken with the robust losses as the solver applies them (Ceres' corrector):
// rows a loss down-weights scatter as the M-estimator weighs them, which under Huber at 1
// sigma is 0.57 times what their Jacobian states for Gaussian rows. Errors that change over the
// log or noise larger than stated make observed exceed expected; the mean part of an error
// common to every stretch (a prior that pulls the estimate off the rows' optimum) does not.
struct StretchScatter {
  struct Source {
    std::string name;
    Eigen::MatrixXd observed;
    Eigen::MatrixXd expected;
    Eigen::MatrixXd model;
    Eigen::VectorXd degrees_of_freedom;
  };
  bool ok = false;  // false when J^T J is singular or the problem does not evaluate
  int stretches = 0;
  std::vector<Source> sources;
  std::vector<int> offsets;  // first stacked coordinate of each block, as BlockCovariance's
  Eigen::VectorXd variance;  // diagonal of J^T J's inverse at the stacked coordinates
};

// One source's excess along one coordinate: observed / expected, sqrt, and the sigma it
// widens (the factor is this source's alone).
struct ScatterExcess {
  std::string source;
  int coordinate = 0;
  double ratio = 1.0;         // sqrt(observed / expected)
  double sigma_factor = 1.0;  // sigma with this source's share widened / sigma before
};

// Whether Eq. C8 judges coordinate c of `source`: not where the solve fits its stretches
// almost wholly (expected_cc below 1e-3 model_cc, where the difference is rounding).
bool JudgesScatter(const StretchScatter::Source& source, int c);

// `covariance` with, for every coordinate c and source s whose observed_cc / expected_cc exceeds
// the chi-square quantile at `significance` over its degrees of freedom (divided by them), the
// source's share of the variance scaled by that ratio: the variance grows by
// (observed_cc / expected_cc - 1) model_cc / variance_c covariance_cc (the source's fraction
// of J^T J's variance, applied to the covariance given, which may complete J^T J, Eqs. C5-C6)
// and the covariance is scaled as D C D, which keeps its correlations. No variance is widened
// past `max_variance` (the prior's: a direction whose estimate errs more is held at its prior)
// nor narrowed. Only coordinates JudgesScatter judges are widened. A covariance that is not
// ok, or a scatter that is not, is returned as it is. `excess`, when given, receives the
// coordinates a source widens by 1 % or more, largest sigma factor first.
BlockCovariance WidenedForScatter(const BlockCovariance& covariance, const StretchScatter& scatter,
                                  double significance, const Eigen::VectorXd& max_variance,
                                  std::vector<ScatterExcess>* excess = nullptr);

}  // namespace estimation
}  // namespace autocal
