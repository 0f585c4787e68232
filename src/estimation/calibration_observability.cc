#include "autocal/estimation/calibration_observability.h"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <Eigen/OrderingMethods>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <algorithm>
#include <cmath>
#include <iomanip>
#include <map>
#include <optional>
#include <sstream>
#include <unordered_set>
#include <utility>

#include "autocal/common/error.h"
#include "autocal/common/parallel_for.h"
#include "autocal/factors/prior_factors.h"
#include "autocal/geometry/quaternion_plus.h"
#include "autocal/geometry/so3.h"
#include "estimation/ldlt_columns.h"
#include "estimation/normal_equations.h"
#include "estimation/residual_curvature.h"

namespace autocal {
namespace estimation {

namespace {

bool IsRotation(const EstimatedBlock& block) {
  return block.manifold == sensors::BlockManifold::kRightQuaternion;
}

Eigen::Quaterniond AsQuaternion(const double* xyzw) {
  return Eigen::Quaterniond(xyzw[3], xyzw[0], xyzw[1], xyzw[2]);
}

Eigen::VectorXd TangentFromPrior(const EstimatedBlock& block) {
  return BlockMinus(block, block.data, block.prior.data());
}

// Direction i of a block is informed by the data (not held at its prior) when its posterior
// sigma is well below its prior's and within a few times its limit.
bool Informed(const EstimatedBlock& block, int i, double posterior_sigma) {
  return posterior_sigma <= block.max_posterior_to_prior_sigma * block.prior_sigma(i) &&
         posterior_sigma <= block.max_kept_sigma_to_limit * block.max_observable_sigma;
}

// Direction i of a block is judged for plausibility when the data inform it (Informed), or
// when its prior was stated and the data hold about a quarter or more of the prior's
// information (posterior sigma at most 0.9 of the prior's) and determine it within
// max_kept_sigma_to_limit times its limit: the drive then contradicts what the user stated,
// and holding the stated value would hide it. Under a weak default prior, or determined more
// weakly than that, a held direction may wander in a flat or mismodelled cost
// (docs/calibration.md, "A solve that ends ...").
constexpr double kMaxJudgedPosteriorToPriorSigma = 0.9;

bool Judged(const EstimatedBlock& block, int i, double posterior_sigma) {
  return Informed(block, i, posterior_sigma) ||
         (block.prior_stated &&
          posterior_sigma <= kMaxJudgedPosteriorToPriorSigma * block.prior_sigma(i) &&
          posterior_sigma <= block.max_kept_sigma_to_limit * block.max_observable_sigma);
}

void Step(const EstimatedBlock& block, const Eigen::VectorXd& step) {
  BlockPlus(block, step, block.data);
}

double SigmaOf(const Eigen::MatrixXd& S, int row) { return std::sqrt(std::max(0.0, S(row, row))); }

// The rows of the joint vector split into informed (O) and held (U) directions, and every
// block's difference from its prior.
struct Partition {
  Eigen::VectorXd difference;
  std::vector<int> observable, unobservable;
  Eigen::VectorXd prior_variance_u;  // the held directions' prior sigma squared
};

Partition PartitionDirections(const std::vector<EstimatedBlock>& blocks,
                              const BlockCovariance& covariance) {
  const Eigen::MatrixXd& S = covariance.matrix;
  Partition out;
  out.difference.resize(S.rows());
  std::vector<double> prior_variance_u;
  for (size_t b = 0; b < blocks.size(); ++b) {
    const int first = covariance.offsets[b];
    out.difference.segment(first, blocks[b].size) = TangentFromPrior(blocks[b]);
    for (int i = 0; i < blocks[b].size; ++i) {
      if (Informed(blocks[b], i, SigmaOf(S, first + i))) {
        out.observable.push_back(first + i);
      } else {
        out.unobservable.push_back(first + i);
        prior_variance_u.push_back(blocks[b].prior_sigma(i) * blocks[b].prior_sigma(i));
      }
    }
  }
  out.prior_variance_u = Eigen::Map<const Eigen::VectorXd>(
      prior_variance_u.data(), static_cast<Eigen::Index>(prior_variance_u.size()));
  return out;
}

// S restricted to `rows` x `cols`.
Eigen::MatrixXd Pick(const Eigen::MatrixXd& S, const std::vector<int>& rows,
                     const std::vector<int>& cols) {
  Eigen::MatrixXd m(rows.size(), cols.size());
  for (size_t r = 0; r < rows.size(); ++r) {
    for (size_t c = 0; c < cols.size(); ++c) {
      m(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c)) = S(rows[r], cols[c]);
    }
  }
  return m;
}

// Eq. C1, and Eq. C2: the held values are the nominal ones, whose own error has the prior
// covariance P_U; through the gain K = S_OU S_UU^-1 it reaches the conditioned directions,
// so their covariance is S_OO - K S_UO + K P_U K^T. Returns the step of every direction and
// subtracts the reduction from *conditioned (a copy of S).
Eigen::VectorXd Condition(const Eigen::MatrixXd& S, const Partition& part,
                          Eigen::MatrixXd* conditioned) {
  Eigen::VectorXd step = Eigen::VectorXd::Zero(S.rows());
  if (part.unobservable.empty()) return step;
  const Eigen::MatrixXd S_ou = Pick(S, part.observable, part.unobservable);
  const Eigen::LDLT<Eigen::MatrixXd> S_uu(Pick(S, part.unobservable, part.unobservable));
  Eigen::VectorXd d_u(part.unobservable.size());
  for (size_t u = 0; u < part.unobservable.size(); ++u) {
    d_u(static_cast<Eigen::Index>(u)) = part.difference(part.unobservable[u]);
  }
  const Eigen::MatrixXd gain = S_uu.solve(S_ou.transpose()).transpose();
  const Eigen::VectorXd shift = -gain * d_u;
  const Eigen::MatrixXd reduction =
      gain * S_ou.transpose() - gain * part.prior_variance_u.asDiagonal() * gain.transpose();
  const std::vector<int>& o = part.observable;
  for (size_t i = 0; i < o.size(); ++i) {
    step(o[i]) = shift(static_cast<Eigen::Index>(i));
    for (size_t j = 0; j < o.size(); ++j) {
      (*conditioned)(o[i], o[j]) -=
          reduction(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j));
    }
  }
  for (int u : part.unobservable) step(u) = -part.difference(u);
  return step;
}

// x (tangent units) in the block's display units, to three digits.
std::string Displayed(const EstimatedBlock& block, double x) {
  std::ostringstream v;
  v << std::setprecision(3) << x * block.display_scale << ' ' << block.display_unit;
  return v.str();
}

// The warning for direction i of `block`, held at its prior with posterior sigma `after`: the
// drive added little to the prior, or it determined the direction, but too weakly to be worth
// more than the prior's centre (Informed's two tests).
std::string HeldWarning(const EstimatedBlock& block, int i, double after) {
  const auto value = [&](double x) { return Displayed(block, x); };
  const std::string& name = block.direction_names[static_cast<size_t>(i)];
  const double prior = block.prior_sigma(i);
  if (after <= block.max_posterior_to_prior_sigma * prior) {
    std::ostringstream times;
    times << std::setprecision(3) << block.max_kept_sigma_to_limit;
    return name + ": determined by the drive too weakly to keep (sigma " + value(after) +
           " after the solve, above " + times.str() + " times its limit of " +
           value(block.max_observable_sigma) + "; prior " + value(prior) + "); held at " +
           block.prior_source;
  }
  // Above the prior's sigma (beyond rounding) the data's information about this direction is
  // not positive semidefinite (Eq. C5): the data alone have no minimum there.
  const bool wider = after > prior * (1.0 + 1e-6);
  return name + ": not excited by the drive (sigma " + value(after) + " after the solve, prior " +
         value(prior) + (wider ? ": alone, the data would not hold it anywhere" : "") +
         "); held at " + block.prior_source;
}

// The flags, sigmas and warnings of one block whose first row is `first`, after the step.
void Report(const EstimatedBlock& block, int first, const Eigen::MatrixXd& S,
            const Eigen::MatrixXd& conditioned, const std::vector<int>& unobservable,
            BlockObservability* out) {
  Eigen::VectorXd sigma =
      conditioned.diagonal().segment(first, block.size).cwiseMax(0.0).cwiseSqrt();
  std::vector<bool> flags(static_cast<size_t>(block.size), true);
  for (int i = 0; i < block.size; ++i) {
    const std::string& name = block.direction_names[static_cast<size_t>(i)];
    const bool held =
        std::find(unobservable.begin(), unobservable.end(), first + i) != unobservable.end();
    if (held) {
      flags[static_cast<size_t>(i)] = false;
      sigma(i) = block.prior_sigma(i);
      out->warnings.push_back(HeldWarning(block, i, SigmaOf(S, first + i)));
    } else if (!(sigma(i) <= block.max_observable_sigma)) {
      // Informed, but not to the accuracy asked for: the estimate is kept (it is better
      // than the nominal value) with its sigma, and not reported as observable.
      flags[static_cast<size_t>(i)] = false;
      out->warnings.push_back(name + ": only partly determined by the drive (sigma " +
                              Displayed(block, sigma(i)) + ", limit " +
                              Displayed(block, block.max_observable_sigma) +
                              "); the estimate is kept and not reported as observable");
    }
  }
  std::vector<bool> held(static_cast<size_t>(block.size));
  for (int i = 0; i < block.size; ++i) {
    held[static_cast<size_t>(i)] =
        std::find(unobservable.begin(), unobservable.end(), first + i) != unobservable.end();
  }
  out->observable.push_back(flags);
  out->held.push_back(held);
  out->sigma.push_back(sigma);
}

// J^T J of every residual block at the current values (robust losses applied as the solver
// applies them), over the tangent coordinates of the problem's variable blocks.
struct GaussNewtonHessian {
  bool ok = true;                  // false when a residual block failed to evaluate
  Eigen::SparseMatrix<double> H;   // lower triangle
  internal::BlockOffsets offsets;  // first tangent column of each variable block
};

// Residual blocks whose Jacobian is evaluated at once for J^T J.
constexpr size_t kResidualBlocksPerStretch = 16384;

// J in column-major form: for each column, the rows holding it and their values.
struct ColumnMajor {
  std::vector<int> start;  // column c's entries are [start[c], start[c + 1])
  std::vector<int> row;
  std::vector<double> value;
};

ColumnMajor ColumnsOf(const ceres::CRSMatrix& J) {
  const int n = J.num_cols;
  ColumnMajor out;
  out.start.assign(static_cast<size_t>(n) + 1, 0);
  for (const int c : J.cols) ++out.start[static_cast<size_t>(c) + 1];
  for (int c = 0; c < n; ++c) out.start[c + 1] += out.start[c];
  out.row.resize(J.cols.size());
  out.value.resize(J.cols.size());
  std::vector<int> fill(out.start.begin(), out.start.end() - 1);
  for (int k = 0; k < J.num_rows; ++k) {
    for (int e = J.rows[k]; e < J.rows[k + 1]; ++e) {
      const int at = fill[static_cast<size_t>(J.cols[e])]++;
      out.row[at] = k;
      out.value[at] = J.values[e];
    }
  }
  return out;
}

// Splits the columns into `parts` contiguous ranges of about equal work, column j's work
// being the nonzeros of the rows that hold it (an upper bound of its products): part p is
// [first[p], first[p + 1]).
std::vector<int> BalancedColumnRanges(const ceres::CRSMatrix& J, const ColumnMajor& columns,
                                      int parts) {
  const int n = J.num_cols;
  std::vector<int64_t> work_before(static_cast<size_t>(n) + 1, 0);
  for (int j = 0; j < n; ++j) {
    int64_t work = 0;
    for (int a = columns.start[j]; a < columns.start[j + 1]; ++a) {
      const int k = columns.row[a];
      work += J.rows[k + 1] - J.rows[k];
    }
    work_before[j + 1] = work_before[j] + work;
  }
  // The targets grow with p and work_before never decreases, so the ranges are ordered.
  std::vector<int> first(static_cast<size_t>(parts) + 1, n);
  first[0] = 0;
  for (int p = 1; p < parts; ++p) {
    const int64_t target = work_before.back() * p / parts;
    first[p] = static_cast<int>(std::lower_bound(work_before.begin(), work_before.end(), target) -
                                work_before.begin());
  }
  return first;
}

// Gustavson's product for columns [begin, end) of the lower triangle, with a dense
// accumulator: column j sums J(k, j) J(k, c) over the rows k that hold column j, for c >= j.
void AppendLowerGramColumns(const ceres::CRSMatrix& J, const ColumnMajor& columns, int begin,
                            int end, std::vector<Eigen::Triplet<double>>* entries) {
  std::vector<double> sum(static_cast<size_t>(J.num_cols), 0.0);
  std::vector<int> seen(static_cast<size_t>(J.num_cols), -1);
  std::vector<int> touched;
  for (int j = begin; j < end; ++j) {
    touched.clear();
    for (int a = columns.start[j]; a < columns.start[j + 1]; ++a) {
      const int k = columns.row[a];
      for (int e = J.rows[k]; e < J.rows[k + 1]; ++e) {
        const int c = J.cols[e];
        if (c < j) continue;
        if (seen[c] != j) {
          seen[c] = j;
          sum[c] = 0.0;
          touched.push_back(c);
        }
        sum[c] += columns.value[a] * J.values[e];
      }
    }
    for (const int c : touched) entries->emplace_back(c, j, sum[c]);
  }
}

// The lower triangle of J^T J. Its cost is the sum over rows of their nonzeros squared,
// whatever the columns' fill. Ranges of columns go to num_threads threads; each column is
// summed alone in one fixed order, so the result does not depend on the thread count.
Eigen::SparseMatrix<double> LowerGram(const ceres::CRSMatrix& J, int num_threads) {
  const ColumnMajor columns = ColumnsOf(J);
  const int parts = ParallelChunks(J.num_cols, num_threads);
  const std::vector<int> first = BalancedColumnRanges(J, columns, parts);
  std::vector<std::vector<Eigen::Triplet<double>>> entries(static_cast<size_t>(parts));
  ParallelFor(0, parts, num_threads, [&](int64_t begin, int64_t end, int) {
    for (int64_t p = begin; p < end; ++p) {
      AppendLowerGramColumns(J, columns, first[p], first[p + 1], &entries[static_cast<size_t>(p)]);
    }
  });
  size_t total = 0;
  for (const auto& part : entries) total += part.size();
  entries[0].reserve(total);
  for (size_t p = 1; p < entries.size(); ++p) {
    entries[0].insert(entries[0].end(), entries[p].begin(), entries[p].end());
    std::vector<Eigen::Triplet<double>>().swap(entries[p]);
  }
  Eigen::SparseMatrix<double> lower(J.num_cols, J.num_cols);
  lower.setFromTriplets(entries[0].begin(), entries[0].end());
  return lower;
}

// The information of `ids` at the current values, J^T J over `variables`' columns, times
// `scale`: J is evaluated for a stretch of residual blocks at a time and the stretches' grams
// summed, so a long log's Jacobian is never held whole (on a 10-minute log it and its copies
// were a third of the calibration's peak memory). Nullopt when a residual block fails to
// evaluate.
std::optional<Eigen::SparseMatrix<double>> InformationOf(
    ceres::Problem* problem, internal::VariableColumns* variables,
    const std::vector<ceres::ResidualBlockId>& ids, double scale, int num_threads) {
  Eigen::SparseMatrix<double> H(variables->columns, variables->columns);
  for (size_t first = 0; first < ids.size(); first += kResidualBlocksPerStretch) {
    const size_t end = std::min(ids.size(), first + kResidualBlocksPerStretch);
    variables->evaluate.residual_blocks.assign(ids.begin() + static_cast<std::ptrdiff_t>(first),
                                               ids.begin() + static_cast<std::ptrdiff_t>(end));
    ceres::CRSMatrix crs;
    if (!problem->Evaluate(variables->evaluate, nullptr, nullptr, nullptr, &crs)) {
      return std::nullopt;
    }
    H = Eigen::SparseMatrix<double>(H + scale * LowerGram(crs, num_threads));
  }
  return H;
}

// J^T J in two parts: over the residual blocks outside `scaled` and, times `scale`, over those
// inside it (empty when it has none).
struct SplitHessian {
  bool ok = true;                             // false when a residual block failed to evaluate
  Eigen::SparseMatrix<double> plain, scaled;  // lower triangles
  internal::BlockOffsets offsets;
};

SplitHessian EvaluateSplitHessian(ceres::Problem* problem, int num_threads,
                                  const ScaledInformation& scaled, double scale) {
  SplitHessian out;
  internal::VariableColumns variables = internal::VariableColumnsOf(problem);
  variables.evaluate.num_threads = num_threads;
  out.offsets = variables.offsets;
  std::vector<ceres::ResidualBlockId> residual_blocks;
  problem->GetResidualBlocks(&residual_blocks);
  const std::unordered_set<ceres::ResidualBlockId> in_scaled(scaled.residual_blocks.begin(),
                                                             scaled.residual_blocks.end());
  std::vector<ceres::ResidualBlockId> plain, rescaled;
  for (const ceres::ResidualBlockId id : residual_blocks) {
    (in_scaled.count(id) > 0 ? rescaled : plain).push_back(id);
  }
  std::optional<Eigen::SparseMatrix<double>> information =
      InformationOf(problem, &variables, plain, 1.0, num_threads);
  out.ok = information.has_value();
  if (out.ok) out.plain = std::move(*information);
  if (out.ok && !rescaled.empty()) {
    information = InformationOf(problem, &variables, rescaled, scale, num_threads);
    out.ok = information.has_value();
    if (out.ok) out.scaled = std::move(*information);
  }
  return out;
}

GaussNewtonHessian Sum(const SplitHessian& split, double scale) {
  GaussNewtonHessian out;
  out.ok = split.ok;
  out.offsets = split.offsets;
  out.H = split.scaled.nonZeros() == 0
              ? split.plain
              : Eigen::SparseMatrix<double>(split.plain + scale * split.scaled);
  return out;
}

GaussNewtonHessian EvaluateGaussNewtonHessian(ceres::Problem* problem, int num_threads,
                                              const ScaledInformation& scaled) {
  return Sum(EvaluateSplitHessian(problem, num_threads, scaled, scaled.scale), 1.0);
}

// Whether an LDL^T factorization's pivots show a positive definite matrix: each pivot above
// a relative floor at the rounding level (a rank-deficient Jacobian leaves pivots there).
bool FullRank(const Eigen::VectorXd& pivots) {
  if (pivots.size() == 0) return true;
  const double floor = 1e-14 * pivots.cwiseAbs().maxCoeff();
  return (pivots.array() > floor).all();
}

}  // namespace

Eigen::VectorXd StackedPriorVariances(const std::vector<EstimatedBlock>& blocks,
                                      const std::vector<int>& offsets) {
  int size = 0;
  for (const EstimatedBlock& block : blocks) size += block.size;
  Eigen::VectorXd out(size);
  for (size_t b = 0; b < blocks.size(); ++b) {
    out.segment(offsets[b], blocks[b].size) = blocks[b].prior_sigma.cwiseAbs2();
  }
  return out;
}

Eigen::VectorXd BlockMinus(const EstimatedBlock& block, const double* x, const double* x0) {
  if (IsRotation(block)) {
    const Eigen::Quaterniond q0 = AsQuaternion(x0);
    const Eigen::Quaterniond q = AsQuaternion(x);
    return geometry::Log(Eigen::Quaterniond(q0.conjugate() * q));
  }
  return Eigen::Map<const Eigen::VectorXd>(x, block.size) -
         Eigen::Map<const Eigen::VectorXd>(x0, block.size);
}

void BlockPlus(const EstimatedBlock& block, const Eigen::VectorXd& step, double* x) {
  if (IsRotation(block)) {
    Eigen::Map<Eigen::Quaterniond> q(x);
    q = geometry::QuaternionPlus(Eigen::Quaterniond(q), Eigen::Vector3d(step));
    return;
  }
  Eigen::Map<Eigen::VectorXd>(x, block.size) += step;
}

EstimatedBlock BlockOf(sensors::CalibrationBlockId id, sensors::Calibration* calibration) {
  const sensors::CalibrationBlockInfo& info = sensors::CalibrationBlock(id);
  EstimatedBlock block;
  block.id = id;
  block.name = info.name;
  block.data = info.values(calibration);
  block.size = info.tangent_size;
  block.manifold = info.manifold;
  block.direction_names.assign(info.direction_names.begin(),
                               info.direction_names.begin() + info.tangent_size);
  block.display_scale = info.display_scale;
  block.display_unit = info.display_unit;
  return block;
}

std::vector<ceres::ResidualBlockId> AddBlockPriors(const std::vector<EstimatedBlock>& blocks,
                                                   const factors::LossOptions& loss,
                                                   ceres::Problem* problem) {
  std::vector<ceres::ResidualBlockId> ids;
  for (const EstimatedBlock& block : blocks) {
    const Eigen::MatrixXd sqrt_information = factors::SqrtInformationFromSigmas(block.prior_sigma);
    ceres::CostFunction* cost =
        IsRotation(block) ? static_cast<ceres::CostFunction*>(new factors::QuaternionPriorFactor(
                                AsQuaternion(block.prior.data()), sqrt_information))
                          : new factors::VectorPriorFactor(block.prior, sqrt_information);
    ids.push_back(problem->AddResidualBlock(cost, factors::MakeLossFunction(loss), block.data));
  }
  return ids;
}

namespace {

// Columns of H^-1 at the blocks' tangent coordinates, stacked in block order (a block held
// constant keeps zeros), from a sparse LDL^T of H with the blocks in problem order.
struct InverseColumns {
  bool ok = false;                        // false when H is singular or not finite
  int size = 0;                           // the blocks' stacked coordinates
  internal::RowMajorMatrix columns;       // rows: H's; columns: the stacked coordinates
  std::vector<int> offsets;               // first stacked coordinate of each block
  std::vector<std::pair<int, int>> rows;  // (row of H, stacked coordinate) of variable blocks
};

// The fill-reducing permutation P of H's pattern (P H P^T factorizes with little fill), as
// Eigen's SimplicialLDLT computes it: AMD on the symmetric pattern. Kept in `ordering` for the
// next matrix of the same problem; one already there and of H's size is used as it is.
const Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int>& OrderingFor(
    const Eigen::SparseMatrix<double>& H, CovarianceOrdering* ordering) {
  if (ordering->P.size() != H.rows()) {
    const Eigen::SparseMatrix<double> symmetric = H.selfadjointView<Eigen::Lower>();
    Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> inverse;
    Eigen::AMDOrdering<int>()(symmetric, inverse);
    ordering->P = inverse.inverse();
  }
  return ordering->P;
}

// The sparse LDL^T of H under the fill-reducing permutation P: H^-1 B = P^T L^-T D^-1 L^-1 P B.
struct HessianFactor {
  bool ok = false;  // false when H is singular or not finite
  Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> P;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Upper, Eigen::NaturalOrdering<int>>
      ldlt;

  HessianFactor(const GaussNewtonHessian& hessian, CovarianceOrdering* ordering)
      : P(OrderingFor(hessian.H, ordering)) {
    Eigen::SparseMatrix<double> permuted(hessian.H.rows(), hessian.H.cols());
    permuted.selfadjointView<Eigen::Upper>() =
        hessian.H.selfadjointView<Eigen::Lower>().twistedBy(P);
    ldlt.compute(permuted);
    ok = ldlt.info() == Eigen::Success && FullRank(ldlt.vectorD());
  }

  // B^T H^-1 B (ok only), through the forward half of the solve.
  Eigen::MatrixXd QuadraticForm(const Eigen::MatrixXd& B) const {
    const Eigen::MatrixXd permuted = P * B;
    const internal::RowMajorMatrix W =
        internal::ForwardColumns(ldlt.matrixL().nestedExpression(), permuted);
    return W.transpose() * ldlt.vectorD().asDiagonal().inverse() * W;
  }

  // H^-1 B (ok only).
  internal::RowMajorMatrix Solve(const Eigen::MatrixXd& B) const {
    const Eigen::MatrixXd permuted = P * B;
    return P.inverse() *
           internal::SolveColumns(ldlt.matrixL().nestedExpression(), ldlt.vectorD(), permuted);
  }
};

// The tangent size the problem gives the block at `it` (its columns up to the next block's).
int TangentColumns(const GaussNewtonHessian& hessian, internal::BlockOffsets::const_iterator it) {
  int next = static_cast<int>(hessian.H.rows());
  for (const auto& [data, first] : hessian.offsets) {
    if (first > it->second) next = std::min(next, first);
  }
  return next - it->second;
}

// Throws autocal::Error when the problem gives `block` another tangent size than the block
// states (a manifold that holds some of its axes): its directions would read other columns.
void RequireTangentSize(const EstimatedBlock& block, const GaussNewtonHessian& hessian,
                        internal::BlockOffsets::const_iterator it) {
  const int columns = TangentColumns(hessian, it);
  if (columns == block.size) return;
  throw Error("the covariance of " + block.name + ": the problem gives it " +
              std::to_string(columns) + " tangent directions where the block states " +
              std::to_string(block.size));
}

InverseColumns InverseColumnsAt(const std::vector<EstimatedBlock>& blocks,
                                const GaussNewtonHessian& hessian, CovarianceOrdering* ordering,
                                const HessianFactor* given = nullptr) {
  InverseColumns out;
  for (const EstimatedBlock& block : blocks) {
    out.offsets.push_back(out.size);
    out.size += block.size;
  }
  Eigen::MatrixXd unit = Eigen::MatrixXd::Zero(hessian.H.rows(), out.size);
  for (size_t a = 0; a < blocks.size(); ++a) {
    const auto it = hessian.offsets.find(blocks[a].data);
    if (it == hessian.offsets.end()) continue;
    RequireTangentSize(blocks[a], hessian, it);
    for (int i = 0; i < blocks[a].size; ++i) {
      unit(it->second + i, out.offsets[a] + i) = 1.0;
      out.rows.emplace_back(it->second + i, out.offsets[a] + i);
    }
  }
  std::optional<HessianFactor> own;
  if (given == nullptr) given = &own.emplace(hessian, ordering);
  if (!given->ok) return out;
  out.columns = given->Solve(unit);
  out.ok = out.columns.allFinite();
  return out;
}

// Row k of J's sensitivity of every stacked coordinate, J_k H^-1 e (Eq. E1's and C8's rows).
Eigen::VectorXd RowSensitivity(const ceres::CRSMatrix& J, int k, const InverseColumns& inverse) {
  Eigen::VectorXd sensitivity = Eigen::VectorXd::Zero(inverse.size);
  for (int e = J.rows[k]; e < J.rows[k + 1]; ++e) {
    sensitivity += J.values[e] * inverse.columns.row(J.cols[e]).transpose();
  }
  return sensitivity;
}

// The blocks' part of H^-1, symmetrized; zeros and not ok when `inverse` is not ok.
BlockCovariance CovarianceOf(const InverseColumns& inverse) {
  BlockCovariance out;
  out.offsets = inverse.offsets;
  out.matrix = Eigen::MatrixXd::Zero(inverse.size, inverse.size);
  if (!inverse.ok) return out;
  for (const auto& [h_row, row] : inverse.rows) {
    for (const auto& [h_col, col] : inverse.rows)
      out.matrix(row, col) = inverse.columns(h_row, col);
  }
  out.matrix = 0.5 * (out.matrix + out.matrix.transpose()).eval();
  out.ok = out.matrix.allFinite();
  return out;
}

// Nothing estimated: an empty covariance, which is valid.
BlockCovariance EmptyCovariance() {
  BlockCovariance out;
  out.ok = true;
  return out;
}

}  // namespace

BlockCovariance ComputeBlockCovariance(const std::vector<EstimatedBlock>& blocks,
                                       ceres::Problem* problem, int num_threads,
                                       const std::vector<ceres::ResidualBlockId>& exact,
                                       const ScaledInformation& scaled,
                                       CovarianceOrdering* ordering) {
  if (blocks.empty()) return EmptyCovariance();
  GaussNewtonHessian hessian = EvaluateGaussNewtonHessian(problem, num_threads, scaled);
  if (!hessian.ok) return BlockCovariance();
  if (!exact.empty()) {
    const std::vector<Eigen::Triplet<double>> curvature =
        internal::ResidualCurvature(problem, exact, hessian.offsets);
    Eigen::SparseMatrix<double> term(hessian.H.rows(), hessian.H.cols());
    term.setFromTriplets(curvature.begin(), curvature.end());
    hessian.H = Eigen::SparseMatrix<double>(hessian.H + term);
  }
  CovarianceOrdering own;
  if (ordering == nullptr) ordering = &own;
  return CovarianceOf(InverseColumnsAt(blocks, hessian, ordering));
}

ErrorBudget ComputeErrorBudget(const std::vector<EstimatedBlock>& blocks, ceres::Problem* problem,
                               const std::vector<ResidualSource>& sources, int num_threads,
                               const ScaledInformation& scaled, CovarianceOrdering* ordering) {
  ErrorBudget out;
  for (const ResidualSource& source : sources) out.sources.push_back(source.name);
  if (blocks.empty()) {
    out.covariance = EmptyCovariance();
    out.scaled_covariance = out.covariance;
    out.ok = true;
    return out;
  }
  // One J for both: the solve weighs every residual as is, the scaled covariance does not.
  const SplitHessian split = EvaluateSplitHessian(problem, num_threads, scaled, 1.0);
  if (!split.ok) return out;
  CovarianceOrdering own;
  if (ordering == nullptr) ordering = &own;
  const InverseColumns inverse = InverseColumnsAt(blocks, Sum(split, 1.0), ordering);
  out.covariance = CovarianceOf(inverse);
  out.scaled_covariance =
      scaled.scale == 1.0 || split.scaled.nonZeros() == 0
          ? out.covariance
          : CovarianceOf(InverseColumnsAt(blocks, Sum(split, scaled.scale), ordering));
  out.share = Eigen::MatrixXd::Zero(inverse.size, static_cast<Eigen::Index>(sources.size()));
  out.spread = out.share;
  if (!inverse.ok) return out;
  internal::VariableColumns variables = internal::VariableColumnsOf(problem);
  variables.evaluate.num_threads = num_threads;
  for (size_t s = 0; s < sources.size(); ++s) {
    const std::vector<ceres::ResidualBlockId>& ids = sources[s].residual_blocks;
    for (size_t first = 0; first < ids.size(); first += kResidualBlocksPerStretch) {
      const size_t end = std::min(ids.size(), first + kResidualBlocksPerStretch);
      variables.evaluate.residual_blocks.assign(ids.begin() + static_cast<std::ptrdiff_t>(first),
                                                ids.begin() + static_cast<std::ptrdiff_t>(end));
      std::vector<double> r;
      ceres::CRSMatrix J;
      if (!problem->Evaluate(variables.evaluate, nullptr, &r, nullptr, &J)) return out;
      for (int k = 0; k < J.num_rows; ++k) {
        const Eigen::VectorXd sensitivity = RowSensitivity(J, k, inverse);
        out.share.col(s) += sensitivity * r[static_cast<size_t>(k)];
        out.spread.col(s) += sensitivity.cwiseAbs2();
      }
    }
  }
  out.spread = out.spread.cwiseSqrt();
  out.ok = out.covariance.ok && out.share.allFinite() && out.spread.allFinite();
  return out;
}

namespace {

// One stretch's part of Eq. C8: its share U = S^T r of the blocks' error, S = J X the rows'
// sensitivities (X: H^-1's columns at the blocks), V = S^T S its covariance under the noise
// model, Y = J^T S, and (once Complete has run) E[U U^T] at the fitted residuals,
// V - Y^T H^-1 Y.
struct StretchShare {
  Eigen::VectorXd share;
  Eigen::MatrixXd model;
  Eigen::MatrixXd Y;
  Eigen::MatrixXd expected;

  void Complete(const HessianFactor& factor) {
    expected = model - factor.QuadraticForm(Y);
    Y.resize(0, 0);
  }
};

// The stretch's share at the residuals r + J step when `step` is given (at the values
// `problem` holds otherwise): Y^T step more.
std::optional<StretchShare> ShareOfStretch(ceres::Problem* problem,
                                           const internal::VariableColumns& variables,
                                           const InverseColumns& inverse,
                                           const Eigen::VectorXd* step) {
  std::vector<double> r;
  ceres::CRSMatrix J;
  if (!problem->Evaluate(variables.evaluate, nullptr, &r, nullptr, &J)) return std::nullopt;
  const Eigen::Index m = inverse.size;
  Eigen::MatrixXd S = Eigen::MatrixXd::Zero(J.num_rows, m);
  StretchShare out;
  out.Y = Eigen::MatrixXd::Zero(inverse.columns.rows(), m);
  for (int k = 0; k < J.num_rows; ++k) {
    S.row(k) = RowSensitivity(J, k, inverse).transpose();
    for (int e = J.rows[k]; e < J.rows[k + 1]; ++e) out.Y.row(J.cols[e]) += J.values[e] * S.row(k);
  }
  out.share = S.transpose() * Eigen::Map<const Eigen::VectorXd>(r.data(), J.num_rows);
  if (step != nullptr) out.share += out.Y.transpose() * *step;
  out.model = S.transpose() * S;
  return out;
}

// -H^-1 J^T r over every residual block of `problem`: the Gauss-Newton step from its values.
// J^T r is summed on one thread: Ceres' threads would each sum the blocks the scheduling gave
// them, and the step's last bits would follow the thread count and the run.
std::optional<Eigen::VectorXd> GaussNewtonStep(ceres::Problem* problem,
                                               internal::VariableColumns variables,
                                               const HessianFactor& factor) {
  variables.evaluate.residual_blocks.clear();
  variables.evaluate.num_threads = 1;
  std::vector<double> gradient;
  if (!problem->Evaluate(variables.evaluate, nullptr, nullptr, &gradient, nullptr)) {
    return std::nullopt;
  }
  const Eigen::MatrixXd g = Eigen::Map<const Eigen::VectorXd>(
      gradient.data(), static_cast<Eigen::Index>(gradient.size()));
  return Eigen::VectorXd(-factor.Solve(g).col(0));
}

// Source's Eq. C8 sums over `stretches` runs of its residual blocks; the runs are evaluated in
// turn (Ceres evaluates one problem at a time) and their solves run num_threads at once.
std::optional<StretchScatter::Source> ScatterOfSource(ceres::Problem* problem,
                                                      internal::VariableColumns* variables,
                                                      const ResidualSource& source, int stretches,
                                                      const InverseColumns& inverse,
                                                      const HessianFactor& factor, int num_threads,
                                                      const Eigen::VectorXd* step) {
  const Eigen::Index m = inverse.size;
  StretchScatter::Source out{source.name, Eigen::MatrixXd::Zero(m, m), Eigen::MatrixXd::Zero(m, m),
                             Eigen::MatrixXd::Zero(m, m), Eigen::VectorXd::Zero(m)};
  Eigen::VectorXd expected_squares = Eigen::VectorXd::Zero(m);  // sum_b diag(E_b)^2
  const size_t n = source.residual_blocks.size();
  const size_t runs = static_cast<size_t>(stretches);
  const size_t group = static_cast<size_t>(std::max(1, num_threads));
  Eigen::VectorXd total = Eigen::VectorXd::Zero(m);                      // sum_b U_b
  Eigen::MatrixXd Y = Eigen::MatrixXd::Zero(inverse.columns.rows(), m);  // sum_b Y_b
  for (size_t first_run = 0; first_run < runs; first_run += group) {
    std::vector<StretchShare> parts;
    for (size_t b = first_run; b < std::min(runs, first_run + group); ++b) {
      const auto first = static_cast<std::ptrdiff_t>(n * b / runs);
      const auto end = static_cast<std::ptrdiff_t>(n * (b + 1) / runs);
      variables->evaluate.residual_blocks.assign(source.residual_blocks.begin() + first,
                                                 source.residual_blocks.begin() + end);
      std::optional<StretchShare> part = ShareOfStretch(problem, *variables, inverse, step);
      if (!part) return std::nullopt;
      Y += part->Y;
      parts.push_back(std::move(*part));
    }
    ParallelFor(0, static_cast<int64_t>(parts.size()), num_threads,
                [&](int64_t begin, int64_t end, int) {
                  for (int64_t b = begin; b < end; ++b) {
                    parts[static_cast<size_t>(b)].Complete(factor);
                  }
                });
    for (const StretchShare& part : parts) {
      out.observed += part.share * part.share.transpose();
      total += part.share;
      out.model += part.model;
      out.expected += part.expected;
      expected_squares += part.expected.diagonal().cwiseAbs2();
    }
  }
  for (Eigen::Index c = 0; c < m; ++c) {
    const double sum = out.expected(c, c);
    out.degrees_of_freedom(c) =
        expected_squares(c) > 0.0 ? std::max(1.0, sum * sum / expected_squares(c) - 1.0) : 1.0;
  }
  // About the stretches' mean: E[T T^T] = sum_b V_b - Y^T H^-1 Y for T = sum_b U_b, since
  // E[U_b U_c^T] = -Y_b^T H^-1 Y_c for b != c.
  const double weight = 1.0 / static_cast<double>(runs);
  out.observed -= weight * total * total.transpose();
  out.expected -= weight * (out.model - factor.QuadraticForm(Y));
  out.expected *= source.share_ratio;
  return out;
}

}  // namespace

StretchScatter ComputeStretchScatter(const std::vector<EstimatedBlock>& blocks,
                                     ceres::Problem* problem,
                                     const std::vector<ResidualSource>& sources, int stretches,
                                     int num_threads, CovarianceOrdering* ordering,
                                     bool at_gauss_newton_step) {
  if (stretches < 2) throw Error("ComputeStretchScatter: stretches must be >= 2");
  StretchScatter out;
  out.stretches = stretches;
  if (blocks.empty()) return out;
  const GaussNewtonHessian hessian = EvaluateGaussNewtonHessian(problem, num_threads, {});
  if (!hessian.ok) return out;
  CovarianceOrdering own;
  if (ordering == nullptr) ordering = &own;
  const HessianFactor factor(hessian, ordering);
  const InverseColumns inverse = InverseColumnsAt(blocks, hessian, ordering, &factor);
  if (!inverse.ok) return out;
  out.offsets = inverse.offsets;
  out.variance = CovarianceOf(inverse).matrix.diagonal();
  internal::VariableColumns variables = internal::VariableColumnsOf(problem);
  variables.evaluate.num_threads = num_threads;
  std::optional<Eigen::VectorXd> step;
  if (at_gauss_newton_step) {
    step = GaussNewtonStep(problem, variables, factor);
    if (!step || !step->allFinite()) return out;
  }
  for (const ResidualSource& source : sources) {
    if (source.residual_blocks.size() < static_cast<size_t>(stretches)) continue;
    std::optional<StretchScatter::Source> scatter =
        ScatterOfSource(problem, &variables, source, stretches, inverse, factor, num_threads,
                        step ? &*step : nullptr);
    if (!scatter) return out;
    out.sources.push_back(std::move(*scatter));
  }
  out.ok = true;
  for (const StretchScatter::Source& source : out.sources) {
    out.ok = out.ok && source.observed.allFinite() && source.expected.allFinite();
  }
  return out;
}

std::vector<std::string> ImplausibleDirections(const std::vector<EstimatedBlock>& blocks,
                                               const BlockCovariance& covariance,
                                               double max_sigmas) {
  std::vector<std::string> out;
  for (size_t b = 0; b < blocks.size(); ++b) {
    const EstimatedBlock& block = blocks[b];
    const Eigen::VectorXd difference = TangentFromPrior(block);
    for (int i = 0; i < block.size; ++i) {
      if (covariance.ok &&
          !Judged(block, i, SigmaOf(covariance.matrix, covariance.offsets[b] + i))) {
        continue;
      }
      const double sigmas = std::abs(difference(i)) / block.prior_sigma(i);
      if (!(sigmas <= max_sigmas)) {  // also catches NaN
        std::ostringstream text;
        text << std::setprecision(3) << block.direction_names[static_cast<size_t>(i)] << " moved "
             << difference(i) * block.display_scale << ' ' << block.display_unit
             << " from the nominal value, " << sigmas << " prior sigmas";
        out.push_back(text.str());
      }
    }
  }
  return out;
}

namespace {

// Frees `blocks` in `problem` under their priors, and on destruction holds them constant again
// and removes those priors.
class FreedBlocks {
 public:
  FreedBlocks(const std::vector<EstimatedBlock>& blocks, ceres::Problem* problem)
      : blocks_(blocks), problem_(problem) {
    priors_ = AddBlockPriors(blocks_, factors::LossOptions(), problem_);
    for (const EstimatedBlock& block : blocks_) problem_->SetParameterBlockVariable(block.data);
  }
  ~FreedBlocks() {
    for (const ceres::ResidualBlockId id : priors_) problem_->RemoveResidualBlock(id);
    for (const EstimatedBlock& block : blocks_) problem_->SetParameterBlockConstant(block.data);
  }
  FreedBlocks(const FreedBlocks&) = delete;
  FreedBlocks& operator=(const FreedBlocks&) = delete;

 private:
  const std::vector<EstimatedBlock>& blocks_;
  ceres::Problem* problem_;
  std::vector<ceres::ResidualBlockId> priors_;
};

std::string MovedFixedDirection(const EstimatedBlock& block, int i, double step, double sigma) {
  std::ostringstream text;
  text << std::setprecision(3) << block.direction_names[static_cast<size_t>(i)]
       << " is fixed, but the data would move it by " << step * block.display_scale << ' '
       << block.display_unit << " (sigma " << sigma * block.display_scale << ' '
       << block.display_unit << ", " << std::abs(step) / sigma << " sigma)";
  return text.str();
}

// The blocks of `fixed` FixedDirectionsTheDataMove judges, each prior centred at its fixed
// value, with their indices in `fixed`.
std::vector<EstimatedBlock> JudgedFixedBlocks(const std::vector<EstimatedBlock>& fixed,
                                              const ceres::Problem& problem,
                                              std::vector<size_t>* index) {
  std::vector<EstimatedBlock> judged;
  for (size_t b = 0; b < fixed.size(); ++b) {
    EstimatedBlock block = fixed[b];
    if (!problem.HasParameterBlock(block.data) || !problem.IsParameterBlockConstant(block.data) ||
        !(block.prior_sigma.array() > 0.0).all() || !block.prior_sigma.allFinite()) {
      continue;
    }
    block.prior = Eigen::Map<const Eigen::VectorXd>(block.data, block.prior.size());
    judged.push_back(std::move(block));
    index->push_back(b);
  }
  return judged;
}

// `covariance` of `judged` widened by the sources' scatter over the log at the Gauss-Newton
// step's residuals (Eq. C8), up to the blocks' prior variances; as it is when the scatter
// cannot be computed.
BlockCovariance WidenedAtTheStep(const std::vector<EstimatedBlock>& judged, ceres::Problem* problem,
                                 const BlockCovariance& covariance, const ScatterSettings& settings,
                                 int num_threads, CovarianceOrdering* ordering) {
  const StretchScatter scatter = ComputeStretchScatter(
      judged, problem, settings.sources, settings.stretches, num_threads, ordering, true);
  if (!scatter.ok) return covariance;
  return WidenedForScatter(covariance, scatter, settings.significance,
                           StackedPriorVariances(judged, covariance.offsets), nullptr);
}

}  // namespace

std::vector<FixedDirectionMove> FixedDirectionsTheDataMove(
    const std::vector<EstimatedBlock>& fixed, ceres::Problem* problem, int num_threads,
    double max_sigmas, const std::vector<ceres::ResidualBlockId>& exact,
    const ScaledInformation& scaled, const ScatterSettings& scatter) {
  std::vector<size_t> index;
  const std::vector<EstimatedBlock> judged = JudgedFixedBlocks(fixed, *problem, &index);
  if (judged.empty()) return {};
  ResidualSource all{"all", {}};
  problem->GetResidualBlocks(&all.residual_blocks);
  const FreedBlocks freed(judged, problem);
  // H^-1 J^T r is minus the Gauss-Newton step (ComputeErrorBudget); the priors, centred at the
  // fixed values, add nothing to it.
  // One fill-reducing ordering for both: the exact rows add to blocks J^T J already couples.
  CovarianceOrdering ordering;
  const ErrorBudget budget =
      ComputeErrorBudget(judged, problem, {all}, num_threads, ScaledInformation(), &ordering);
  if (!budget.ok) return {};
  BlockCovariance covariance =
      ComputeBlockCovariance(judged, problem, num_threads, exact, scaled, &ordering);
  if (!covariance.ok) covariance = budget.covariance;
  if (scatter.stretches > 0) {
    covariance = WidenedAtTheStep(judged, problem, covariance, scatter, num_threads, &ordering);
  }
  std::vector<FixedDirectionMove> out;
  for (size_t b = 0; b < judged.size(); ++b) {
    const EstimatedBlock& block = judged[b];
    for (int i = 0; i < block.size; ++i) {
      const int row = covariance.offsets[b] + i;
      const double sigma = SigmaOf(covariance.matrix, row);
      const double step = -budget.share(budget.covariance.offsets[b] + i, 0);
      if (!Informed(block, i, sigma) || !(std::abs(step) > max_sigmas * sigma)) continue;
      out.push_back({index[b], i, step, sigma, MovedFixedDirection(block, i, step, sigma)});
    }
  }
  return out;
}

BlockObservability HoldUnobservableDirections(const std::vector<EstimatedBlock>& blocks,
                                              const BlockCovariance& covariance) {
  const Partition part = PartitionDirections(blocks, covariance);
  Eigen::MatrixXd conditioned = covariance.matrix;
  const Eigen::VectorXd step = Condition(covariance.matrix, part, &conditioned);
  BlockObservability out;
  for (size_t b = 0; b < blocks.size(); ++b) {
    const int first = covariance.offsets[b];
    Step(blocks[b], step.segment(first, blocks[b].size));
    Report(blocks[b], first, covariance.matrix, conditioned, part.unobservable, &out);
  }
  return out;
}

bool AnyHeld(const BlockObservability& observability) {
  for (const std::vector<bool>& block : observability.held) {
    if (std::find(block.begin(), block.end(), true) != block.end()) return true;
  }
  return false;
}

bool AllHeld(const BlockObservability& observability) {
  for (const std::vector<bool>& block : observability.held) {
    if (std::find(block.begin(), block.end(), false) != block.end()) return false;
  }
  return AnyHeld(observability);
}

std::vector<ceres::ResidualBlockId> AddHeldDirectionPriors(
    const std::vector<EstimatedBlock>& blocks, const BlockObservability& observability,
    ceres::Problem* problem) {
  std::vector<ceres::ResidualBlockId> out;
  for (size_t b = 0; b < blocks.size(); ++b) {
    const EstimatedBlock& block = blocks[b];
    Eigen::MatrixXd sqrt_information = Eigen::MatrixXd::Zero(block.size, block.size);
    for (int i = 0; i < block.size; ++i) {
      if (observability.held[b][static_cast<size_t>(i)]) {
        sqrt_information(i, i) = 1.0 / (kHeldSigmaFraction * block.prior_sigma(i));
      }
    }
    if (sqrt_information.isZero()) continue;
    ceres::CostFunction* cost =
        IsRotation(block)
            ? static_cast<ceres::CostFunction*>(new factors::QuaternionPriorFactor(
                  AsQuaternion(block.data), Eigen::Matrix3d(sqrt_information)))
            : new factors::VectorPriorFactor(
                  Eigen::Map<const Eigen::VectorXd>(block.data, block.size), sqrt_information);
    out.push_back(problem->AddResidualBlock(cost, nullptr, block.data));
  }
  return out;
}

void SetHeldDirectionsToPrior(const std::vector<EstimatedBlock>& blocks,
                              const BlockObservability& observability) {
  for (size_t b = 0; b < blocks.size(); ++b) {
    const EstimatedBlock& block = blocks[b];
    const std::vector<bool>& held = observability.held[b];
    if (std::find(held.begin(), held.end(), true) == held.end()) continue;
    if (!IsRotation(block)) {
      for (int i = 0; i < block.size; ++i) {
        if (held[static_cast<size_t>(i)]) block.data[i] = block.prior(i);
      }
      continue;
    }
    Eigen::Vector3d difference = TangentFromPrior(block);
    for (int i = 0; i < 3; ++i) {
      if (held[static_cast<size_t>(i)]) difference(i) = 0.0;
    }
    Eigen::Map<Eigen::Quaterniond>(block.data) =
        geometry::QuaternionPlus(AsQuaternion(block.prior.data()), difference);
  }
}

}  // namespace estimation
}  // namespace autocal
