#pragma once

// The calibration blocks an estimator solves for, seen as one vector: their priors, their
// joint covariance after a solve, and which of their directions the data excited
// (docs/calibration.md, "Observability and uncertainty"). A direction the data left at its
// prior is held there and the others are conditioned on it (Eq. C1-C2), so that a drive that
// cannot see a block does not report a value the data never determined.
//
//   std::vector<EstimatedBlock> blocks = ...;    // BlockOf(id, &calibration) + prior, limits
//   AddBlockPriors(blocks, loss, &problem);     // before the solve
//   const BlockCovariance covariance = ComputeBlockCovariance(blocks, &problem);  // after it
//   if (covariance.ok) observability = HoldUnobservableDirections(blocks, covariance);

#include <ceres/ceres.h>

#include <Eigen/Core>
#include <string>
#include <vector>

#include "autocal/estimation/stretch_scatter.h"
#include "autocal/factors/loss.h"
#include "autocal/sensors/calibration.h"
#include "autocal/sensors/calibration_blocks.h"

namespace autocal {
namespace estimation {

// One calibration block under estimation, in tangent units (rad, m, s) unless named.
struct EstimatedBlock {
  sensors::CalibrationBlockId id = sensors::CalibrationBlockId::kLidarRotation;
  std::string name;        // in words, e.g. "T_I_L rotation"
  double* data = nullptr;  // the parameter block's ambient values (in the calibration solved)
  int size = 0;            // tangent size: 3 or 1
  sensors::BlockManifold manifold = sensors::BlockManifold::kEuclidean;
  Eigen::VectorXd prior;  // ambient value of the prior (the nominal calibration)
  std::string prior_source = "the nominal value";  // what the prior's centre is, in words
  Eigen::VectorXd prior_sigma;                     // per tangent direction
  // The prior's sigma was stated (a problem's prior mode, a dataset's nominal uncertainty),
  // not a weak default that only keeps the problem regular.
  bool prior_stated = false;
  // A direction whose posterior sigma exceeds this is not observable.
  double max_observable_sigma = 0.0;
  // It is held at its prior (unexcited) when its posterior sigma exceeds this fraction of its
  // prior sigma (the data added little to the prior) or this multiple of max_observable_sigma.
  double max_posterior_to_prior_sigma = 0.5;
  double max_kept_sigma_to_limit = 4.0;
  std::vector<std::string> direction_names;  // in words, one per tangent direction
  double display_scale = 1.0;                // tangent units to display units
  std::string display_unit;
};

// Block `id` of `calibration` as the block table describes it (sensors/calibration_blocks.h):
// data, size, manifold, names and display. The prior, its sigma and the limits are the
// caller's to set.
EstimatedBlock BlockOf(sensors::CalibrationBlockId id, sensors::Calibration* calibration);

// The blocks' prior variances, prior_sigma^2, stacked as `offsets` (a BlockCovariance's) lays
// the blocks out: the most Eq. C8 widens a variance to.
Eigen::VectorXd StackedPriorVariances(const std::vector<EstimatedBlock>& blocks,
                                      const std::vector<int>& offsets);

// x - x0 in the block's tangent (a rotation: Log(q0^-1 q)), and x <- x + step (q Exp(step));
// x and x0 hold the block's ambient values.
Eigen::VectorXd BlockMinus(const EstimatedBlock& block, const double* x, const double* x0);
void BlockPlus(const EstimatedBlock& block, const Eigen::VectorXd& step, double* x);

// A prior at the block's prior value on every block (Gaussian, sigma per direction); returns
// the residual blocks it added, in block order.
std::vector<ceres::ResidualBlockId> AddBlockPriors(const std::vector<EstimatedBlock>& blocks,
                                                   const factors::LossOptions& loss,
                                                   ceres::Problem* problem);

// The joint covariance of the blocks' tangent coordinates, blocks in order: the blocks' part
// of (J^T J)^-1 over every variable block of `problem` (robust losses applied as the solver
// applies them), from a sparse LDL^T with the blocks in problem order, so the result does not
// depend on where they live in memory. A rotation block must carry
// geometry::RightQuaternionManifold in `problem`; a block held constant gets zeros; a block the
// problem gives another tangent size (a manifold holding some axes) is refused (autocal::Error).
// J and J^T J are formed on num_threads threads; the result does not depend on the count.
struct BlockCovariance {
  bool ok = false;  // false when J^T J is singular (a pivot at the rounding level) or not finite
  Eigen::MatrixXd matrix;
  std::vector<int> offsets;  // first row of each block
};
//
// The residual blocks `exact` enter with their exact Hessian, J^T J + rho' sum r d2r
// (docs/calibration.md, Eq. C5): where a residual's derivative is itself noise, Gauss-Newton
// counts it as information the cost does not have. The information of `scaled`'s residual
// blocks is multiplied by its scale (a robust loss's sandwich, Eq. C6).
struct ScaledInformation {
  std::vector<ceres::ResidualBlockId> residual_blocks;
  double scale = 1.0;
};
//
// The fill-reducing ordering of J^T J's pattern (Eigen's AMD) costs about as much as the
// factorization on a long log. Given an `ordering`, the first call computes it and later calls
// on the same problem reuse it (any ordering gives the same covariance; the same one the same
// bits); without one, each call computes its own.
struct CovarianceOrdering {
  Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> P;
};
BlockCovariance ComputeBlockCovariance(const std::vector<EstimatedBlock>& blocks,
                                       ceres::Problem* problem, int num_threads = 1,
                                       const std::vector<ceres::ResidualBlockId>& exact = {},
                                       const ScaledInformation& scaled = {},
                                       CovarianceOrdering* ordering = nullptr);

// Where the error of the blocks comes from (docs/evaluation.md, Eq. E1): at the values
// `problem` holds (the truth of a simulated log), H^-1 J^T r over every variable block (H =
// J^T J, robust losses applied as the solver applies them) is truth - estimate to first order.
// Per source s of residual blocks, `share` is H^-1 J_s^T r_s and `spread` the share's standard
// deviation were the source's whitened residuals N(0, I); the spreads' squares sum to the
// covariance's diagonal when every residual block belongs to a source. `scaled_covariance` is
// ComputeBlockCovariance's with `scaled` (the Cramér–Rao bound at the truth, Eq. C6), from the
// same J.
struct ResidualSource {
  std::string name;
  std::vector<ceres::ResidualBlockId> residual_blocks;
  // What the source's share varies by, against the least-squares share its Jacobian states,
  // when its rows follow the source's noise model: 1 for least squares, below 1 under a
  // robust loss (factors::RowPull). Eq. C8 takes its expectation with it; the error budget
  // does not use it.
  double share_ratio = 1.0;
};
struct ErrorBudget {
  bool ok = false;             // false when J^T J is singular or the problem does not evaluate
  BlockCovariance covariance;  // the blocks' part of H^-1, as ComputeBlockCovariance's
  BlockCovariance scaled_covariance;  // the same with `scaled`'s information times its scale
  std::vector<std::string> sources;
  Eigen::MatrixXd share;   // rows: the blocks' stacked coordinates; column s: source s's
  Eigen::MatrixXd spread;  // laid out as share
};
ErrorBudget ComputeErrorBudget(const std::vector<EstimatedBlock>& blocks, ceres::Problem* problem,
                               const std::vector<ResidualSource>& sources, int num_threads = 1,
                               const ScaledInformation& scaled = {},
                               CovarianceOrdering* ordering = nullptr);

// How each source's share of the blocks' error scatters over the log against what its noise
// model says (docs/calibration.md, Eq. C8; the result and its use: stretch_scatter.h). A
// source's residual blocks, in the order given (their time order), are cut into `stretches`
// runs of equal count, at the solution `problem` holds or, `at_gauss_newton_step`, at the
// residuals r + J step of the Gauss-Newton step from its values (the expectation assumes the
// least-squares residuals; a problem not at its minimum, such as one whose fixed blocks were
// freed for Eq. C7, has them there to first order). A source with fewer residual blocks than
// stretches is left out. Throws autocal::Error for fewer than two stretches.
StretchScatter ComputeStretchScatter(const std::vector<EstimatedBlock>& blocks,
                                     ceres::Problem* problem,
                                     const std::vector<ResidualSource>& sources, int stretches,
                                     int num_threads = 1, CovarianceOrdering* ordering = nullptr,
                                     bool at_gauss_newton_step = false);

// The directions that the data inform (observable or kept; or held under a stated prior while
// the data hold about a quarter or more of its information, posterior sigma at most 0.9 of
// the prior's and at most max_kept_sigma_to_limit times the limit) and whose estimate lies more
// than max_sigmas prior sigmas from the prior value, as plain-language lines ("... moved 41.2 deg
// from the nominal value, 8.2 prior sigmas"): a solve that went there did not converge to anything
// the priors allow, or the drive contradicts a stated prior. Other directions are not judged: they
// may wander in a flat or mismodelled cost and are held at their prior anyway. Without a covariance
// every direction is judged.
std::vector<std::string> ImplausibleDirections(const std::vector<EstimatedBlock>& blocks,
                                               const BlockCovariance& covariance,
                                               double max_sigmas);

// The blocks a problem holds fixed that the data contradict (docs/calibration.md, Eq. C7): at
// the solution `problem` holds, each block of `fixed` that is a constant parameter block of it
// is freed, under a prior at its fixed value with the block's prior_sigma (so that a direction
// the data do not inform stays put), and one Gauss-Newton step is taken with every other
// variable block of `problem` free: the step a solve estimating the block would start with.
// Its sigma is the block's part of H^-1 as ComputeBlockCovariance gives it with `exact` and
// `scaled` (Gauss-Newton's where that H is not positive definite). Each direction the data
// inform (Informed: as a direction an estimate would keep) whose step exceeds max_sigmas sigmas
// is returned. With `scatter`'s stretches, that sigma is widened where the sources' rows
// scatter over the log beyond their noise model (Eq. C8, at the Gauss-Newton step's residuals;
// WidenedForScatter up to the block's prior sigma). Not judged: blocks that are not parameter
// blocks of `problem` (a wheel or GNSS clock fixed at zero enters no factor) and blocks stated
// exact (a prior sigma of zero). `problem` is left as it was.
struct ScatterSettings {
  std::vector<ResidualSource> sources;  // in time order each, as ComputeStretchScatter's
  int stretches = 0;                    // 0: the sigma as the noise model gives it
  double significance = 0.001;
};
struct FixedDirectionMove {
  size_t block = 0;  // index into `fixed`
  int direction = 0;
  double step = 0.0;  // tangent units
  double sigma = 0.0;
  // "mount yaw (...) is fixed, but the data would move it by 0.856 deg (sigma 0.131 deg,
  // 6.54 sigma)"
  std::string text;
};
std::vector<FixedDirectionMove> FixedDirectionsTheDataMove(
    const std::vector<EstimatedBlock>& fixed, ceres::Problem* problem, int num_threads,
    double max_sigmas, const std::vector<ceres::ResidualBlockId>& exact = {},
    const ScaledInformation& scaled = {}, const ScatterSettings& scatter = {});

// Directions the data left at their prior (posterior sigma above max_posterior_to_prior_sigma
// of the prior's, or above max_kept_sigma_to_limit times the limit) are held (U): set to
// their prior value, and the others (O) conditioned on them with the prior's error carried
// along (docs/calibration.md, Eq. C1-C2):
//   x_O <- x_O - K (x_U - x0_U),   S_OO <- S_OO - K S_UO + K P_U K^T,   K = S_OU S_UU^-1.
// A direction of O whose sigma then exceeds its block's limit keeps its estimate and sigma
// but is not reported observable. Updates the blocks' data in place; needs covariance.ok.
struct BlockObservability {
  std::vector<std::vector<bool>> observable;  // per block, per direction
  std::vector<std::vector<bool>> held;        // per block, per direction: set to the prior
  std::vector<Eigen::VectorXd> sigma;         // posterior (held directions: the prior's)
  std::vector<std::string> warnings;          // one plain-language line per unobservable one
};
BlockObservability HoldUnobservableDirections(const std::vector<EstimatedBlock>& blocks,
                                              const BlockCovariance& covariance);

// Whether any direction of `observability` was held.
bool AnyHeld(const BlockObservability& observability);
// Whether every direction was held (and there is one): the data determined nothing.
bool AllHeld(const BlockObservability& observability);

// After HoldUnobservableDirections: a prior that pins every held direction at its held value
// (a sigma of kHeldSigmaFraction of its prior sigma; the other directions get no row), so that
// a second solve of `problem` moves the trajectory and the other blocks to the calibration that
// is reported (Eq. C3). Ownership as AddBlockPriors; returns the residual blocks added, for
// their removal after that solve (a held direction is held at a value known only to its prior's
// sigma, which later tests of the problem count: Eq. C7).
constexpr double kHeldSigmaFraction = 1e-6;
std::vector<ceres::ResidualBlockId> AddHeldDirectionPriors(
    const std::vector<EstimatedBlock>& blocks, const BlockObservability& observability,
    ceres::Problem* problem);

// After that solve: every held direction exactly at its prior value again (the solve leaves
// it within kHeldSigmaFraction of a sigma), the other directions as they are.
void SetHeldDirectionsToPrior(const std::vector<EstimatedBlock>& blocks,
                              const BlockObservability& observability);

}  // namespace estimation
}  // namespace autocal
