#pragma once

// Several logs of one vehicle, one calibration (docs/calibration.md, "Several logs"). Each
// log's solve leaves a Gaussian over the calibration blocks: its prior times its data's
// likelihood, with that log's trajectory marginalized out. The logs' data are independent
// given the calibration, so their joint posterior is one prior times every log's likelihood.
// In the tangent at a common reference, with Lambda_i = S_i^-1 (log i's posterior
// information), P_i its prior's and x_i, p_i its estimate and prior centre, its data say
// D_i = Lambda_i - P_i about the centre c_i = D_i^-1 (Lambda_i x_i - P_i p_i), and
//   (M1)  Lambda = P + sum_i G_i,
//   (M2)  Lambda x = P p + sum_i G_i c_i,
// the joint solve's normal equations at the logs' estimates: exact for a linear problem, first
// order otherwise (the logs' estimates lie within a few sigma of each other). G_i = D_i when
// the log's rows scatter as their noise model says; where they scatter more (Eq. C8: the
// widened covariance W_i), c_i's covariance is D_i^-1 (D_i + E_i) D_i^-1 with
// E_i = Lambda_i (W_i - S_i) Lambda_i, and G_i is its inverse.

#include <Eigen/Core>
#include <vector>

#include "autocal/estimation/calibration_observability.h"
#include "autocal/sensors/calibration.h"

namespace autocal {
namespace estimation {

// What one log says of the calibration blocks before any direction was held: the values of
// its solve, its blocks (priors, limits, names; their data pointers are not used) and their
// joint covariance, blocks in order: `covariance` as the solve weighted its rows (H^-1 of its
// noise model, Eq. M1-M2's S_i), `widened` where the rows scatter over the log beyond that
// model (docs/calibration.md, Eq. C8: the sigmas the result reports and holds by, W_i).
struct CalibrationPosterior {
  sensors::Calibration solved;
  std::vector<EstimatedBlock> blocks;
  BlockCovariance covariance;
  BlockCovariance widened;

  // The covariance the log reports: `widened` when it was computed, else `covariance`.
  const BlockCovariance& Reported() const { return widened.ok ? widened : covariance; }
};

// The joint Gaussian (Eq. M1-M2). The blocks are the union of the logs' in table order; a
// block's prior is the first log's that estimates it. value holds the fused blocks and, for
// the others, the first log's solved values. blocks' data point into `value`: rebind them
// with BindBlocks after copying.
struct FusedCalibration {
  sensors::Calibration value;
  std::vector<EstimatedBlock> blocks;
  BlockCovariance covariance;
};

// Throws autocal::Error when no posterior is given, one has no covariance, or the combined
// information is not positive definite.
FusedCalibration FuseCalibrationPosteriors(const std::vector<CalibrationPosterior>& logs);

// Eq. M3, whether the logs agree on one block: with V_i the inverse of log i's marginal
// covariance of the block as the log reports it (CalibrationPosterior::Reported) and
// xbar = (sum V_i)^-1 sum V_i x_i,
//   T = sum_i (x_i - xbar)^T V_i (x_i - xbar)  ~  chi^2((n - 1) d)
// for n logs and a block of d directions when one true value underlies them all. Shared priors
// make the logs' errors positively correlated, so T errs low: a disagreement found is real.
struct BlockAgreement {
  sensors::CalibrationBlockId id = sensors::CalibrationBlockId::kLidarRotation;
  std::vector<size_t> logs;  // the logs that estimate the block, at least two
  double chi_square = 0.0;
  int degrees_of_freedom = 0;
  double p_value = 1.0;  // P(chi^2 > T)
  // The pair of logs and the direction that differ most, in sigma of their difference:
  // difference = x_b - x_a (tangent units; a rotation at log a's value), z = |difference| /
  // sqrt(sigma_a^2 + sigma_b^2).
  size_t log_a = 0, log_b = 0;
  int direction = 0;
  double difference = 0.0;
  double z = 0.0;
};
// One entry per block that two or more logs estimate, in table order. Throws autocal::Error
// when a log has no covariance.
std::vector<BlockAgreement> AgreementOfLogs(const std::vector<CalibrationPosterior>& logs);

// Points every block's data at its values in *calibration.
void BindBlocks(sensors::Calibration* calibration, std::vector<EstimatedBlock>* blocks);

}  // namespace estimation
}  // namespace autocal
