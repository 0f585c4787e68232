#include "estimation/normal_equations.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "autocal/common/error.h"

namespace autocal {
namespace estimation {
namespace internal {

double AccumulateNormalEquations(
    ceres::Problem* problem, const std::vector<ceres::ResidualBlockId>& ids,
    const BlockOffsets& offsets, Eigen::MatrixXd* H, Eigen::VectorXd* b, const char* what,
    const std::function<void(const double* block, RowMajorMatrix* jacobian)>& transform) {
  // Buffers reused across residual blocks.
  std::vector<double*> params;
  std::vector<RowMajorMatrix> tangent;
  std::vector<double*> jacobian_ptrs;
  Eigen::VectorXd residual;
  struct TouchedBlock {
    int offset;
    const RowMajorMatrix* jacobian;
  };
  std::vector<TouchedBlock> touched;
  double total_cost = 0.0;
  for (ceres::ResidualBlockId id : ids) {
    problem->GetParameterBlocksForResidualBlock(id, &params);
    const int num_residuals = problem->GetCostFunctionForResidualBlock(id)->num_residuals();
    // Ceres returns these Jacobians in tangent coordinates (manifolds applied). Only the block
    // pairs this residual touches are accumulated (a point group touches a few small blocks of
    // a much larger system).
    tangent.resize(params.size());
    jacobian_ptrs.assign(params.size(), nullptr);
    touched.clear();
    for (size_t k = 0; k < params.size(); ++k) {
      const auto offset = offsets.find(params[k]);
      if (offset == offsets.end()) continue;  // constant block
      tangent[k].resize(num_residuals, problem->ParameterBlockTangentSize(params[k]));
      jacobian_ptrs[k] = tangent[k].data();
      touched.push_back({offset->second, &tangent[k]});
    }
    residual.resize(num_residuals);
    double cost = 0.0;
    if (!problem->EvaluateResidualBlock(id, /*apply_loss_function=*/true, &cost, residual.data(),
                                        jacobian_ptrs.data())) {
      throw Error(std::string(what) + ": a residual block failed to evaluate");
    }
    if (!std::isfinite(cost) || !residual.allFinite()) {
      throw Error(std::string(what) + ": non-finite Jacobians or residuals");
    }
    total_cost += cost;
    for (size_t k = 0; k < params.size(); ++k) {
      if (jacobian_ptrs[k] == nullptr) continue;
      if (!tangent[k].allFinite()) {
        throw Error(std::string(what) + ": non-finite Jacobians or residuals");
      }
      if (transform) transform(params[k], &tangent[k]);
    }
    for (size_t x = 0; x < touched.size(); ++x) {
      const RowMajorMatrix& J_x = *touched[x].jacobian;
      const int gx = touched[x].offset;
      b->segment(gx, J_x.cols()).noalias() += J_x.transpose().lazyProduct(residual);
      for (size_t y = 0; y <= x; ++y) {
        // Only the block below the diagonal (or on it) is accumulated.
        const bool x_below = gx >= touched[y].offset;
        const RowMajorMatrix& J_lo = x_below ? *touched[y].jacobian : J_x;
        const RowMajorMatrix& J_hi = x_below ? J_x : *touched[y].jacobian;
        const int g_hi = std::max(gx, touched[y].offset);
        const int g_lo = std::min(gx, touched[y].offset);
        H->block(g_hi, g_lo, J_hi.cols(), J_lo.cols()).noalias() +=
            J_hi.transpose().lazyProduct(J_lo);
      }
    }
  }
  return total_cost;
}

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
