#pragma once

// The calibration blocks an offline calibration estimates, seen as one vector: their priors,
// their joint covariance, and which directions the drive excited (docs/calibration.md,
// "Observability and uncertainty").

#include <string>
#include <vector>

#include <ceres/ceres.h>

#include <Eigen/Core>

#include "autocal/factors/loss.h"

namespace autocal {
namespace pipeline {

struct CalibrationBlock {
  std::string name;         // e.g. "T_I_L rotation"
  double* data = nullptr;   // the parameter block (in the calibration being solved)
  int size = 0;             // tangent size: 3 or 1
  bool rotation = false;    // a quaternion [x, y, z, w]; tangent = right perturbation (rad)
  Eigen::VectorXd prior;    // ambient value of the prior (the nominal calibration)
  Eigen::VectorXd prior_sigma;  // per tangent direction
  // A direction whose posterior sigma exceeds this (tangent units) is unobservable.
  double max_observable_sigma = 0.0;
  // It is held at its prior (unexcited) when its posterior sigma exceeds this fraction of its
  // prior sigma (the data added little to the prior) or this multiple of max_observable_sigma.
  double max_posterior_to_prior_sigma = 0.5;
  double max_kept_sigma_to_limit = 4.0;
  std::vector<std::string> direction_names;  // physical words, one per tangent direction
  double display_scale = 1.0;                // tangent units to display units
  std::string display_unit;
};

// A prior at the nominal value on every block (Gaussian, sigma per direction).
void AddBlockPriors(const std::vector<CalibrationBlock>& blocks, const factors::LossOptions& loss,
                    ceres::Problem* problem);

// The joint covariance of the blocks' tangent coordinates, blocks in order.
struct BlockCovariance {
  bool ok = false;
  Eigen::MatrixXd matrix;
  std::vector<int> offsets;  // first row of each block
};
BlockCovariance ComputeBlockCovariance(const std::vector<CalibrationBlock>& blocks,
                                       ceres::Problem* problem);

// The directions that the drive excited (posterior sigma within both limits of their block)
// and whose estimate lies more than max_sigmas prior sigmas from the prior value, as
// plain-language lines ("... moved 41.2 deg from the nominal value, 8.2 prior sigmas"): a solve
// that went there did not converge to anything the priors allow. Unexcited directions are not
// judged: they are held at their prior anyway. Without a covariance every direction is judged.
std::vector<std::string> ImplausibleDirections(const std::vector<CalibrationBlock>& blocks,
                                               const BlockCovariance& covariance,
                                               double max_sigmas);

// Directions the drive left at their prior (posterior sigma above max_posterior_to_prior_sigma
// of the prior's or above max_kept_sigma_to_limit times the limit) are held (U): set to their prior value, and the others (O) conditioned on
// them with the prior's error carried along (docs/calibration.md, Eq. C1-C2):
//   x_O <- x_O - K (x_U - x0_U),   S_OO <- S_OO - K S_UO + K P_U K^T,   K = S_OU S_UU^-1.
// A direction of O whose sigma then exceeds its block's limit keeps its estimate and sigma
// but is not reported observable. Updates the blocks' data in place.
struct BlockObservability {
  std::vector<std::vector<bool>> observable;  // per block, per direction
  std::vector<Eigen::VectorXd> sigma;         // posterior (held directions: the prior's)
  std::vector<std::string> warnings;          // one plain-language line per unobservable one
};
BlockObservability HoldUnobservableDirections(const std::vector<CalibrationBlock>& blocks,
                                              const BlockCovariance& covariance);

}  // namespace pipeline
}  // namespace autocal
