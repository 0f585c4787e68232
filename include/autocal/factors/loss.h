#pragma once

// Robust loss per factor type (docs/factors.md, "Robust losses"). Residuals are whitened,
// so a scale is in standard deviations: Huber with scale 1.5 is quadratic up to 1.5 sigma.

#include <ceres/loss_function.h>

#include <cstdint>
#include <string>

#include "autocal/factors/robust_loss.h"

namespace autocal {
namespace factors {

struct LossOptions {
  // The kinds are ICP's (factors/robust_loss.h); here they act on whitened residuals.
  RobustLoss type = RobustLoss::kNone;
  double scale = 1.0;  // > 0, in whitened units (sigmas)
};

// Per sensor, as a problem file chooses them. Defaults: the IMU and priors are trusted
// (quadratic); wheel slip, GNSS multipath and LiDAR mis-associations are outliers.
struct FactorLossOptions {
  LossOptions imu;
  LossOptions prior;
  LossOptions wheel{RobustLoss::kHuber, 2.0};
  LossOptions gnss{RobustLoss::kCauchy, 3.0};
  LossOptions lidar{RobustLoss::kHuber, 1.0};
};

// The scales a loss accepts, in sigmas: wider ones are no robust loss at all, narrower ones
// no residual at all, and both overflow Ceres' loss arithmetic at the extremes.
constexpr double kMinLossScale = 1e-3;
constexpr double kMaxLossScale = 1e3;

// "none", "<type>" (scale 1) or "<type>:<scale>" / "<type> <scale>", e.g. "huber:1.5";
// <type> as ParseRobustLoss reads it (case-insensitive).
// Throws autocal::Error on an unknown type or a scale outside [kMinLossScale, kMaxLossScale].
LossOptions ParseLossOptions(const std::string& text);

// A new loss function for Problem::AddResidualBlock (which takes ownership), or nullptr for
// kNone (plain least squares). Throws autocal::Error on a scale out of range.
ceres::LossFunction* MakeLossFunction(const LossOptions& options);

// Whether `loss` down-weights a residual of squared whitened norm s: its weight rho'(s) is
// below one half (Huber with scale d beyond 2 d, Cauchy with scale c beyond c). Never for
// a null loss (plain least squares). The rule the residual statistics count by.
bool DownweightedByLoss(const ceres::LossFunction* loss, double s);

// What a residual block's rows pull a solve with against the weight their Jacobian states, for
// the rows' scatter over a log (docs/calibration.md, Eq. C8): rows r whose loss acts on s = |r|^2
// pull with psi = rho'(s) r, and Ceres' corrector gives their Jacobian the weight rho'(s) (it
// scales both by sqrt(rho'), the whole correction where rho'' <= 0: every loss MakeLossFunction
// makes). `pull_squared` sums |psi|^2 and `weight` the rows' weights; their ratio is what a
// block's share of the error varies by against the least-squares share its Jacobian states.
struct RowPull {
  double pull_squared = 0.0;
  double weight = 0.0;
};

// E[RowPull] of one residual block of `dimension` rows N(0, I), under `loss` (nullptr: least
// squares, {dimension, dimension}). For one row, Huber at 1: 0.516 and 0.906, so the share of
// Gaussian rows varies by 0.57 of what their Jacobian states; Cauchy at 3: 0.68.
// Throws autocal::Error for a dimension below 1.
RowPull ExpectedRowPull(const ceres::LossFunction* loss, int dimension);

// The sandwich ratio of a robust loss over whitened residuals r (docs/calibration.md, Eq. C6):
// with psi(r) = rho'(r^2) r and the Gauss-Newton weight w = rho'^2 r^2 / rho that a row of a
// point group carries (Eq. P9), kappa = mean(w) mean(psi^2) / mean(psi')^2 is the M-estimator's
// variance over the one (sum w J^T J)^-1 states, for residuals independent of their rows.
// One for least squares; about 0.96 (Huber at 1) and 0.74 (Cauchy at 1) on Gaussian residuals.
class SandwichRatio {
 public:
  explicit SandwichRatio(const ceres::LossFunction* loss) : loss_(loss) {}
  void Add(double r);
  int64_t count() const { return count_; }
  // 1 without residuals, without a loss or when mean(psi') is not positive.
  double kappa() const;
  // The sums of psi^2 and w over the residuals added (each one's without a loss).
  RowPull pull() const;

 private:
  const ceres::LossFunction* loss_;
  double weight_ = 0.0, psi_squared_ = 0.0, psi_slope_ = 0.0;
  int64_t count_ = 0;
};

}  // namespace factors
}  // namespace autocal
