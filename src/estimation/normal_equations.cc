#include "estimation/normal_equations.h"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <string>

#include "autocal/common/error.h"

namespace autocal {
namespace estimation {
namespace internal {

namespace {

struct TouchedBlock {
  int offset;  // in H
  const RowMajorMatrix* jacobian;
};

// A residual block with this many rows and blocks (a marginalization prior) is accumulated by
// one dense product J^T J of its stacked Jacobian (a blocked matrix product) instead of one
// small product per pair of blocks.
constexpr int kDenseRows = 32;
constexpr size_t kDenseBlocks = 4;

void AccumulateDense(const std::vector<TouchedBlock>& touched, const Eigen::VectorXd& residual,
                     Eigen::MatrixXd* H, Eigen::VectorXd* b, Eigen::MatrixXd* stacked,
                     Eigen::MatrixXd* gram) {
  std::vector<int> column(touched.size() + 1, 0);
  for (size_t x = 0; x < touched.size(); ++x) {
    column[x + 1] = column[x] + static_cast<int>(touched[x].jacobian->cols());
  }
  stacked->resize(residual.size(), column.back());
  for (size_t x = 0; x < touched.size(); ++x) {
    stacked->middleCols(column[x], column[x + 1] - column[x]) = *touched[x].jacobian;
  }
  gram->setZero(column.back(), column.back());
  gram->selfadjointView<Eigen::Lower>().rankUpdate(stacked->transpose());
  const Eigen::VectorXd gradient = stacked->transpose() * residual;
  for (size_t x = 0; x < touched.size(); ++x) {
    const int gx = touched[x].offset;
    const int cx = column[x];
    const int nx = column[x + 1] - cx;
    b->segment(gx, nx) += gradient.segment(cx, nx);
    for (size_t y = 0; y <= x; ++y) {
      const int gy = touched[y].offset;
      const int cy = column[y];
      const int ny = column[y + 1] - cy;
      // gram holds (x, y) for x >= y in its lower triangle; H takes the block below its
      // diagonal.
      if (gx >= gy) {
        H->block(gx, gy, nx, ny) += gram->block(cx, cy, nx, ny);
      } else {
        H->block(gy, gx, ny, nx) += gram->block(cx, cy, nx, ny).transpose();
      }
    }
  }
}

}  // namespace

double AccumulateNormalEquations(
    ceres::Problem* problem, const std::vector<ceres::ResidualBlockId>& ids,
    const BlockOffsets& offsets, Eigen::MatrixXd* H, Eigen::VectorXd* b, const char* what,
    const std::function<void(const double* block, RowMajorMatrix* jacobian)>& transform) {
  // Buffers reused across residual blocks.
  std::vector<double*> params;
  std::vector<RowMajorMatrix> tangent;
  std::vector<double*> jacobian_ptrs;
  Eigen::VectorXd residual;
  std::vector<TouchedBlock> touched;
  Eigen::MatrixXd stacked;
  Eigen::MatrixXd gram;
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
    if (num_residuals >= kDenseRows && touched.size() >= kDenseBlocks) {
      AccumulateDense(touched, residual, H, b, &stacked, &gram);
      continue;
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

VariableColumns VariableColumnsOf(ceres::Problem* problem) {
  VariableColumns out;
  const auto add = [&](double* block) {
    if (out.offsets.count(block) != 0 || problem->IsParameterBlockConstant(block)) return;
    out.evaluate.parameter_blocks.push_back(block);
    out.offsets[block] = out.columns;
    out.columns += problem->ParameterBlockTangentSize(block);
  };
  std::vector<ceres::ResidualBlockId> residual_blocks;
  problem->GetResidualBlocks(&residual_blocks);
  std::vector<double*> named;
  for (const ceres::ResidualBlockId id : residual_blocks) {
    problem->GetParameterBlocksForResidualBlock(id, &named);
    for (double* block : named) add(block);
  }
  std::vector<double*> all;
  problem->GetParameterBlocks(&all);
  for (double* block : all) add(block);
  return out;
}

Eigen::MatrixXd DenseBlockCovariance(ceres::Problem* problem,
                                     const std::vector<const double*>& blocks,
                                     double min_reciprocal_condition_number, int num_threads,
                                     const char* what) {
  VariableColumns variables = VariableColumnsOf(problem);
  ceres::Problem::EvaluateOptions& evaluate = variables.evaluate;
  const BlockOffsets& offset_of = variables.offsets;
  evaluate.num_threads = num_threads;
  ceres::CRSMatrix crs;
  if (!problem->Evaluate(evaluate, nullptr, nullptr, nullptr, &crs)) {
    throw Error(std::string(what) + ": the problem failed to evaluate for the covariance");
  }
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(crs.num_rows, crs.num_cols);
  for (int r = 0; r < crs.num_rows; ++r) {
    for (int k = crs.rows[static_cast<size_t>(r)]; k < crs.rows[static_cast<size_t>(r) + 1]; ++k) {
      J(r, crs.cols[static_cast<size_t>(k)]) = crs.values[static_cast<size_t>(k)];
    }
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(J, Eigen::ComputeThinV);
  const Eigen::VectorXd& s = svd.singularValues();  // decreasing
  Eigen::VectorXd inverse = Eigen::VectorXd::Zero(s.size());
  const double max_squared = s.size() > 0 ? s(0) * s(0) : 0.0;
  for (Eigen::Index i = 0; i < s.size(); ++i) {
    const double squared = s(i) * s(i);
    if (squared > 0.0 && squared >= min_reciprocal_condition_number * max_squared) {
      inverse(i) = 1.0 / squared;
    }
  }
  // The rows of V for the requested blocks.
  int size = 0;
  for (const double* block : blocks) size += problem->ParameterBlockTangentSize(block);
  Eigen::MatrixXd V(size, svd.matrixV().cols());
  int row = 0;
  for (const double* block : blocks) {
    const int tangent = problem->ParameterBlockTangentSize(block);
    const auto found = offset_of.find(const_cast<double*>(block));
    if (found == offset_of.end()) {
      throw Error(std::string(what) + ": a block asked for is not a variable block of the problem");
    }
    const int offset = found->second;
    V.middleRows(row, tangent) = svd.matrixV().middleRows(offset, tangent);
    row += tangent;
  }
  const Eigen::MatrixXd covariance = V * inverse.asDiagonal() * V.transpose();
  return 0.5 * (covariance + covariance.transpose());  // exactly symmetric
}

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
