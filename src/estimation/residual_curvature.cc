#include "estimation/residual_curvature.h"

#include <algorithm>
#include <string>

#include "autocal/common/error.h"
#include "autocal/geometry/manifolds.h"
#include "autocal/geometry/so3.h"

namespace autocal {
namespace estimation {
namespace internal {

namespace {

// The step of the central differences, in tangent units (rad, m, m/s, ...): the cube root of
// the rounding error relative to the Jacobians' own scale of change.
constexpr double kStep = 1e-5;

// One variable parameter block of a residual block.
struct VariableBlock {
  double* data = nullptr;
  int ambient = 0;
  int tangent = 0;
  int column = 0;  // first column in the residual block's stacked Jacobian
  int offset = 0;  // first row of H
  const ceres::Manifold* manifold = nullptr;
  bool rotation = false;
};

class ResidualBlockJacobian {
 public:
  ResidualBlockJacobian(ceres::Problem* problem, ceres::ResidualBlockId id,
                        const BlockOffsets& offsets)
      : problem_(problem), id_(id) {
    problem->GetParameterBlocksForResidualBlock(id, &parameters_);
    rows_ = problem->GetCostFunctionForResidualBlock(id)->num_residuals();
    jacobians_.resize(parameters_.size());
    pointers_.assign(parameters_.size(), nullptr);
    for (size_t p = 0; p < parameters_.size(); ++p) {
      const auto it = offsets.find(parameters_[p]);
      if (it == offsets.end()) continue;
      VariableBlock block;
      block.data = parameters_[p];
      block.ambient = problem->ParameterBlockSize(block.data);
      block.tangent = problem->ParameterBlockTangentSize(block.data);
      block.column = columns_;
      block.offset = it->second;
      block.manifold = problem->GetManifold(block.data);
      block.rotation =
          dynamic_cast<const geometry::RightQuaternionManifold*>(block.manifold) != nullptr;
      if (block.manifold != nullptr && !block.rotation &&
          dynamic_cast<const ceres::SubsetManifold*>(block.manifold) == nullptr) {
        throw Error(
            "residual curvature: a parameter block's manifold is neither a rotation nor "
            "affine in its tangent");
      }
      jacobians_[p].resize(rows_, block.tangent);
      pointers_[p] = jacobians_[p].data();
      columns_ += block.tangent;
      variables_.push_back(block);
    }
  }

  const std::vector<VariableBlock>& variables() const { return variables_; }
  int columns() const { return columns_; }

  // The residual and the stacked tangent Jacobian at the blocks' current values.
  void Evaluate(Eigen::VectorXd* residual, Eigen::MatrixXd* jacobian) {
    residual->resize(rows_);
    double cost = 0.0;
    if (!problem_->EvaluateResidualBlock(id_, false, &cost, residual->data(), pointers_.data()) ||
        !residual->allFinite()) {
      throw Error("residual curvature: a residual block failed to evaluate");
    }
    jacobian->resize(rows_, columns_);
    int column = 0;
    for (const RowMajorMatrix& block : jacobians_) {
      if (block.size() == 0) continue;
      jacobian->middleCols(column, block.cols()) = block;
      column += static_cast<int>(block.cols());
    }
  }

 private:
  ceres::Problem* problem_;
  ceres::ResidualBlockId id_;
  std::vector<double*> parameters_;
  int rows_ = 0;
  int columns_ = 0;
  std::vector<VariableBlock> variables_;
  std::vector<RowMajorMatrix> jacobians_;
  std::vector<double*> pointers_;
};

// x <- x (+) step e_component, in the block's own manifold.
void Perturb(const VariableBlock& block, int component, double step, const double* x, double* out) {
  Eigen::VectorXd delta = Eigen::VectorXd::Zero(block.tangent);
  delta(component) = step;
  if (block.manifold != nullptr) {
    block.manifold->Plus(x, delta.data(), out);
  } else {
    for (int i = 0; i < block.ambient; ++i) out[i] = x[i] + delta(i);
  }
}

// The Jacobian of r(x (+) delta) with respect to delta at delta = step e_component of `block`:
// the tangent Jacobian at x (+) delta times the chart's right Jacobian (Eq. C5).
Eigen::MatrixXd ChartJacobianAt(ResidualBlockJacobian* rb, const VariableBlock& block,
                                int component, double step) {
  // The block's values come back exactly, also when the evaluation throws.
  struct Restore {
    const VariableBlock& block;
    std::vector<double> saved;
    ~Restore() { std::copy(saved.begin(), saved.end(), block.data); }
  } restore{block, std::vector<double>(block.data, block.data + block.ambient)};
  Perturb(block, component, step, restore.saved.data(), block.data);
  Eigen::VectorXd residual;
  Eigen::MatrixXd jacobian;
  rb->Evaluate(&residual, &jacobian);
  if (block.rotation) {
    Eigen::Vector3d delta = Eigen::Vector3d::Zero();
    delta(component) = step;
    jacobian.middleCols<3>(block.column) =
        (jacobian.middleCols<3>(block.column) * geometry::RightJacobian(delta)).eval();
  }
  return jacobian;
}

}  // namespace

BlockCurvature ResidualBlockCurvature(ceres::Problem* problem, ceres::ResidualBlockId id,
                                      const BlockOffsets& offsets) {
  BlockCurvature out;
  ResidualBlockJacobian rb(problem, id, offsets);
  if (rb.columns() == 0) return out;
  Eigen::VectorXd residual;
  Eigen::MatrixXd jacobian;
  rb.Evaluate(&residual, &jacobian);
  // Under a robust loss rho(|r|^2) the term is weighted by rho' (header).
  double rho[3] = {0.0, 1.0, 0.0};
  if (const ceres::LossFunction* loss = problem->GetLossFunctionForResidualBlock(id)) {
    loss->Evaluate(residual.squaredNorm(), rho);
  }
  out.columns.resize(rb.columns(), rb.columns());
  for (const VariableBlock& block : rb.variables()) {
    for (int c = 0; c < block.tangent; ++c) {
      out.h_rows.push_back(block.offset + c);
      const Eigen::MatrixXd difference =
          ChartJacobianAt(&rb, block, c, kStep) - ChartJacobianAt(&rb, block, c, -kStep);
      out.columns.col(block.column + c) =
          rho[1] * difference.transpose() * residual / (2.0 * kStep);
    }
  }
  return out;
}

std::vector<Eigen::Triplet<double>> ResidualCurvature(
    ceres::Problem* problem, const std::vector<ceres::ResidualBlockId>& ids,
    const BlockOffsets& offsets) {
  std::vector<Eigen::Triplet<double>> entries;
  for (const ceres::ResidualBlockId id : ids) {
    const BlockCurvature block = ResidualBlockCurvature(problem, id, offsets);
    // Symmetric up to the differences' truncation: its symmetric part.
    const Eigen::MatrixXd curvature = 0.5 * (block.columns + block.columns.transpose());
    for (Eigen::Index a = 0; a < curvature.rows(); ++a) {
      for (Eigen::Index b = 0; b < curvature.cols(); ++b) {
        if (block.h_rows[a] < block.h_rows[b]) continue;  // H's lower triangle only
        entries.emplace_back(block.h_rows[a], block.h_rows[b], curvature(a, b));
      }
    }
  }
  return entries;
}

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
