#pragma once

// The part of the exact Hessian of 1/2 |r|^2 that Gauss-Newton drops, sum_i r_i d2r_i, for
// chosen residual blocks (docs/calibration.md, Eq. C5). Where a residual's derivative along a
// direction is itself made of the measurements' noise (an attitude's yaw turning a velocity
// change that is mostly noise), J^T J counts that noise squared as information while the cost
// does not curve; adding this term gives the curvature the cost really has there.

#include <ceres/ceres.h>

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <vector>

#include "estimation/normal_equations.h"

namespace autocal {
namespace estimation {
namespace internal {

// sum_i r_i d2r_i of the residual blocks `ids` at their blocks' current values, in the tangent
// coordinates of `offsets` (blocks missing from it are constant), lower triangle only, as
// entries to add to the lower triangle of J^T J. Under a robust loss rho(|r|^2) it is weighted
// by rho', as the exact Hessian weighs it; the loss's own term 2 rho'' J^T r r^T J is left as
// Ceres' corrector leaves it, out wherever rho'' <= 0 (Cauchy, Huber beyond its corner).
// Computed by central differences of each block's tangent Jacobian along each of its variable
// tangent directions, in the chart x (+) delta: a rotation block
// (geometry::RightQuaternionManifold) takes its chart's right Jacobian, every other manifold
// must be affine in its tangent (none, Euclidean, subset). The blocks' values are restored
// exactly, also on a throw. Throws autocal::Error when a block uses another manifold or a
// residual block fails to evaluate.
std::vector<Eigen::Triplet<double>> ResidualCurvature(
    ceres::Problem* problem, const std::vector<ceres::ResidualBlockId>& ids,
    const BlockOffsets& offsets);

// One residual block's term as the differences give it, before ResidualCurvature takes its
// symmetric part: column k is rho' sum_i r_i d(J_c)_i / d delta_k over the block's variable
// tangent coordinates, in the order of its parameter blocks, and h_rows[k] is that coordinate's
// row of H. In the chart x (+) delta the columns are second derivatives of r, symmetric up to
// the differences' truncation. Without the chart's right Jacobian a rotation's column k would
// miss 1/2 e_k x g (g the rotation's part of J^T r): an antisymmetric part, which the
// symmetric part cancels. Empty for a block without variable parameters. Throws as
// ResidualCurvature does.
struct BlockCurvature {
  Eigen::MatrixXd columns;
  std::vector<int> h_rows;
};
BlockCurvature ResidualBlockCurvature(ceres::Problem* problem, ceres::ResidualBlockId id,
                                      const BlockOffsets& offsets);

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
