#pragma once

// The Gauss-Newton normal equations of a set of Ceres residual blocks in tangent coordinates,
// shared by marginalization (Eq. M1) and the window's solver (docs/sliding_window.md, Eq. W5).

#include <ceres/ceres.h>

#include <Eigen/Core>
#include <functional>
#include <map>
#include <vector>

namespace autocal {
namespace estimation {
namespace internal {

using RowMajorMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// Offset of each variable block in the tangent vector.
using BlockOffsets = std::map<double*, int>;

// The variable (non-constant) blocks of a problem in the order its residual blocks first name
// them (then any no residual block names), as evaluation options over them, with each one's
// first tangent column and the columns in all. Not Problem::GetParameterBlocks' order, which is
// the blocks' addresses: a factorization in that order rounds with the heap's layout.
struct VariableColumns {
  ceres::Problem::EvaluateOptions evaluate;  // parameter_blocks: the variable blocks
  BlockOffsets offsets;
  int columns = 0;
};
VariableColumns VariableColumnsOf(ceres::Problem* problem);

// Adds J^T J of the residual blocks `ids`, evaluated at their blocks' current values (robust
// losses applied through Ceres' corrector, Jacobians in tangent coordinates), to the blocks of
// *H on or below its block diagonal (the blocks above it are not touched; the caller mirrors)
// and J^T r to *b. Blocks missing
// from `offsets` (constant ones) get no Jacobian. `transform`, when set, is applied to every
// block's tangent Jacobian first. Returns the residual blocks' cost (1/2 sum of rho). Throws
// autocal::Error, starting with `what`, when a residual block fails to evaluate or is not
// finite.
double AccumulateNormalEquations(
    ceres::Problem* problem, const std::vector<ceres::ResidualBlockId>& ids,
    const BlockOffsets& offsets, Eigen::MatrixXd* H, Eigen::VectorXd* b, const char* what,
    const std::function<void(const double* block, RowMajorMatrix* jacobian)>& transform = {});

// The covariance of `blocks` (tangent coordinates, stacked in their order) from the
// pseudo-inverse of J^T J over every variable block of `problem` at its current values, robust
// losses applied: the singular values s_i of J with (s_i / s_max)^2 below
// min_reciprocal_condition_number are dropped. This is ceres::Covariance's DENSE_SVD with
// null_space_rank -1, but J's columns follow the problem's own block order, where Ceres sorts
// the blocks by address: its result then varies in the last digits from run to run. Throws
// autocal::Error, starting with `what`, when the problem fails to evaluate or a block asked for
// is not a variable block of it.
Eigen::MatrixXd DenseBlockCovariance(ceres::Problem* problem,
                                     const std::vector<const double*>& blocks,
                                     double min_reciprocal_condition_number, int num_threads,
                                     const char* what);

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
