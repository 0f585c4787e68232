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

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
