#pragma once

// Robust losses: the kinds that ICP (lidar/icp.h) applies as iteratively reweighted least
// squares (docs/lidar.md §4.4) and that the factors hand to Ceres (factors/loss.h).
// A residual r (metres) with scale k contributes rho(r) instead of r^2 / 2; each
// Gauss-Newton step solves a weighted least-squares problem with w(r) = rho'(r) / r
// (eq. 4.12):
//   none:    rho = r^2 / 2                                  w = 1
//   huber:   rho = r^2 / 2 (|r| <= k), k |r| - k^2 / 2      w = min(1, k / |r|)
//   cauchy:  rho = k^2 / 2 log(1 + (r / k)^2)               w = 1 / (1 + (r / k)^2)

#include <string>

namespace autocal {
namespace factors {

enum class RobustLoss { kNone, kHuber, kCauchy };

struct RobustKernel {
  RobustLoss loss = RobustLoss::kNone;
  // Residual size (m) where the loss starts to discount: near the inlier noise level.
  double scale_m = 0.1;

  // IRLS weight w(r), eq. (4.12).
  double Weight(double residual_m) const;
  // rho(r), the loss itself.
  double Loss(double residual_m) const;
};

// "none", "huber" or "cauchy", case-insensitive and ignoring surrounding blanks (" Huber "
// is kHuber); throws autocal::Error naming the accepted values otherwise. The one parser for
// every robust loss name: ICP settings and factors::ParseLossOptions.
RobustLoss ParseRobustLoss(const std::string& name);
const char* RobustLossName(RobustLoss loss);

}  // namespace factors
}  // namespace autocal
