#include "autocal/estimation/marginalization.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <set>
#include <string>
#include <utility>

#include "autocal/common/error.h"
#include "autocal/geometry/manifolds.h"
#include "autocal/geometry/so3.h"
#include "estimation/normal_equations.h"

namespace autocal {
namespace estimation {

namespace {

using internal::RowMajorMatrix;

bool IsRightQuaternion(const ceres::Manifold* manifold) {
  return dynamic_cast<const geometry::RightQuaternionManifold*>(manifold) != nullptr;
}

void CheckSupported(const PriorBlock& block) {
  if (block.manifold == nullptr && block.ambient_size == block.tangent_size) return;
  if (IsRightQuaternion(block.manifold)) return;
  throw Error("marginalization supports Euclidean blocks and RightQuaternionManifold blocks only");
}

// Pseudo-inverse square root data of a symmetric PSD matrix: eigenvectors and eigenvalues
// above the threshold.
struct Eigenspace {
  Eigen::MatrixXd vectors;
  Eigen::VectorXd values;
};

Eigenspace SignificantEigenspace(const Eigen::MatrixXd& symmetric,
                                 const MarginalizationOptions& options) {
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> solver(0.5 *
                                                              (symmetric + symmetric.transpose()));
  const Eigen::VectorXd& values = solver.eigenvalues();
  const double largest = values.size() > 0 ? values.maxCoeff() : 0.0;
  const double threshold = std::max(options.absolute_eigenvalue_threshold,
                                    options.relative_eigenvalue_threshold * largest);
  std::vector<int> keep;
  for (int i = 0; i < values.size(); ++i) {
    if (values(i) > threshold) keep.push_back(i);
  }
  Eigenspace out;
  out.vectors.resize(symmetric.rows(), static_cast<Eigen::Index>(keep.size()));
  out.values.resize(static_cast<Eigen::Index>(keep.size()));
  for (size_t j = 0; j < keep.size(); ++j) {
    out.vectors.col(j) = solver.eigenvectors().col(keep[j]);
    out.values(j) = values(keep[j]);
  }
  return out;
}

}  // namespace

MarginalizationPrior::MarginalizationPrior(std::vector<PriorBlock> blocks,
                                           Eigen::MatrixXd sqrt_information, Eigen::VectorXd r0)
    : blocks_(std::move(blocks)),
      sqrt_information_(std::move(sqrt_information)),
      r0_(std::move(r0)) {
  int offset = 0;
  for (const PriorBlock& block : blocks_) {
    CheckSupported(block);
    x0_.emplace_back(Eigen::Map<const Eigen::VectorXd>(block.values, block.ambient_size));
    tangent_offsets_.push_back(offset);
    offset += block.tangent_size;
    mutable_parameter_block_sizes()->push_back(block.ambient_size);
  }
  if (sqrt_information_.cols() != offset || r0_.size() != sqrt_information_.rows()) {
    throw Error("marginalization prior: information and residual sizes do not match the blocks");
  }
  set_num_residuals(static_cast<int>(sqrt_information_.rows()));
}

std::vector<double*> MarginalizationPrior::parameter_pointers() const {
  std::vector<double*> out;
  for (const PriorBlock& block : blocks_) out.push_back(block.values);
  return out;
}

bool MarginalizationPrior::Evaluate(double const* const* parameters, double* residuals,
                                    double** jacobians) const {
  const int n = static_cast<int>(sqrt_information_.cols());
  Eigen::VectorXd dx(n);
  for (size_t i = 0; i < blocks_.size(); ++i) {
    const PriorBlock& block = blocks_[i];
    if (block.manifold == nullptr) {
      dx.segment(tangent_offsets_[i], block.tangent_size) =
          Eigen::Map<const Eigen::VectorXd>(parameters[i], block.ambient_size) - x0_[i];
    } else {
      block.manifold->Minus(parameters[i], x0_[i].data(), dx.data() + tangent_offsets_[i]);
    }
  }
  Eigen::Map<Eigen::VectorXd> r(residuals, num_residuals());
  r = sqrt_information_ * dx + r0_;  // Eq. (M3)
  if (jacobians == nullptr) return true;
  for (size_t i = 0; i < blocks_.size(); ++i) {
    if (jacobians[i] == nullptr) continue;
    const PriorBlock& block = blocks_[i];
    Eigen::Map<RowMajorMatrix> j(jacobians[i], num_residuals(), block.ambient_size);
    const auto s_block = sqrt_information_.middleCols(tangent_offsets_[i], block.tangent_size);
    if (block.manifold == nullptr) {
      j = s_block;
    } else {
      // d Log(x0^-1 x)/d(theta) for x -> x Exp(theta) is Jr^-1(dx); lifted to ambient.
      const Eigen::Vector3d d = dx.segment<3>(tangent_offsets_[i]);
      j = s_block * geometry::RightJacobianInverse(d) *
          geometry::QuaternionMinusJacobian(parameters[i]);
    }
  }
  return true;
}

MarginalConditional::MarginalConditional(std::vector<PriorBlock> marginalized,
                                         std::vector<PriorBlock> kept, Eigen::VectorXd offset,
                                         Eigen::MatrixXd gain)
    : marginalized_(std::move(marginalized)),
      kept_(std::move(kept)),
      offset_(std::move(offset)),
      gain_(std::move(gain)) {
  int m = 0;
  for (const PriorBlock& block : marginalized_) {
    CheckSupported(block);
    marginalized_x0_.emplace_back(
        Eigen::Map<const Eigen::VectorXd>(block.values, block.ambient_size));
    m += block.tangent_size;
  }
  int k = 0;
  for (const PriorBlock& block : kept_) {
    CheckSupported(block);
    kept_x0_.emplace_back(Eigen::Map<const Eigen::VectorXd>(block.values, block.ambient_size));
    k += block.tangent_size;
  }
  if (offset_.size() != m || gain_.rows() != m || gain_.cols() != k) {
    throw Error("marginal conditional: offset and gain sizes do not match the blocks");
  }
}

void MarginalConditional::Apply(const std::vector<const double*>& kept_values,
                                const std::vector<double*>& marginalized_out) const {
  if (kept_values.size() != kept_.size() || marginalized_out.size() != marginalized_.size()) {
    throw Error("marginal conditional: given " + std::to_string(kept_values.size()) + " kept and " +
                std::to_string(marginalized_out.size()) + " marginalized blocks, expected " +
                std::to_string(kept_.size()) + " and " + std::to_string(marginalized_.size()));
  }
  Eigen::VectorXd dk(gain_.cols());
  int offset = 0;
  for (size_t i = 0; i < kept_.size(); ++i) {
    const PriorBlock& block = kept_[i];
    if (block.manifold == nullptr) {
      dk.segment(offset, block.tangent_size) =
          Eigen::Map<const Eigen::VectorXd>(kept_values[i], block.ambient_size) - kept_x0_[i];
    } else {
      block.manifold->Minus(kept_values[i], kept_x0_[i].data(), dk.data() + offset);
    }
    offset += block.tangent_size;
  }
  const Eigen::VectorXd dm = offset_ + gain_ * dk;  // Eq. (M4)
  if (!dm.allFinite()) {
    throw Error("marginal conditional: non-finite step (non-finite kept values?)");
  }
  offset = 0;
  for (size_t j = 0; j < marginalized_.size(); ++j) {
    const PriorBlock& block = marginalized_[j];
    if (block.manifold == nullptr) {
      Eigen::Map<Eigen::VectorXd>(marginalized_out[j], block.ambient_size) =
          marginalized_x0_[j] + dm.segment(offset, block.tangent_size);
    } else {
      block.manifold->Plus(marginalized_x0_[j].data(), dm.data() + offset, marginalized_out[j]);
    }
    offset += block.tangent_size;
  }
}

std::unique_ptr<MarginalizationPrior> Marginalize(ceres::Problem* problem,
                                                  const std::vector<double*>& to_marginalize,
                                                  const MarginalizationOptions& options,
                                                  MarginalConditional* conditional) {
  // 1. The residual blocks touching the blocks to drop, and every variable block they touch:
  //    marginalized ones first, then the kept ones in order of appearance.
  std::set<double*> dropped(to_marginalize.begin(), to_marginalize.end());
  std::vector<ceres::ResidualBlockId> residual_blocks;
  std::set<ceres::ResidualBlockId> seen_residuals;
  for (double* block : to_marginalize) {
    std::vector<ceres::ResidualBlockId> ids;
    problem->GetResidualBlocksForParameterBlock(block, &ids);
    for (ceres::ResidualBlockId id : ids) {
      if (seen_residuals.insert(id).second) residual_blocks.push_back(id);
    }
  }
  std::vector<double*> order;
  for (double* block : to_marginalize) {
    if (!problem->IsParameterBlockConstant(block)) order.push_back(block);
  }
  const size_t num_marginalized_blocks = order.size();
  std::set<double*> in_order(order.begin(), order.end());
  for (ceres::ResidualBlockId id : residual_blocks) {
    std::vector<double*> params;
    problem->GetParameterBlocksForResidualBlock(id, &params);
    for (double* p : params) {
      if (dropped.count(p) || in_order.count(p) || problem->IsParameterBlockConstant(p)) continue;
      in_order.insert(p);
      order.push_back(p);
    }
  }
  internal::BlockOffsets offset_of;
  int n = 0;
  int m = 0;
  for (size_t i = 0; i < order.size(); ++i) {
    offset_of[order[i]] = n;
    n += problem->ParameterBlockTangentSize(order[i]);
    if (i + 1 == num_marginalized_blocks) m = n;
  }

  // 2. Gauss-Newton system of those residuals at the current values, in tangent coordinates.
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(n, n);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(n);
  internal::AccumulateNormalEquations(problem, residual_blocks, offset_of, &H, &b,
                                      "marginalization");
  H.triangularView<Eigen::StrictlyUpper>() = H.transpose();

  // 3. Schur complement onto the kept blocks (Eq. M1), pseudo-inverting H_mm.
  const int k = n - m;
  const Eigenspace mm = SignificantEigenspace(H.topLeftCorner(m, m), options);
  const Eigen::MatrixXd H_mm_pinv =
      mm.vectors * mm.values.cwiseInverse().asDiagonal() * mm.vectors.transpose();
  const Eigen::MatrixXd H_km = H.bottomLeftCorner(k, m);
  std::vector<PriorBlock> marginalized;
  std::vector<PriorBlock> kept;
  for (size_t i = 0; i < order.size(); ++i) {
    PriorBlock block;
    block.values = order[i];
    block.ambient_size = problem->ParameterBlockSize(order[i]);
    block.tangent_size = problem->ParameterBlockTangentSize(order[i]);
    block.manifold = problem->GetManifold(order[i]);
    (i < num_marginalized_blocks ? marginalized : kept).push_back(block);
  }
  if (conditional != nullptr) {  // Eq. (M4)
    *conditional = MarginalConditional(std::move(marginalized), kept, -(H_mm_pinv * b.head(m)),
                                       -(H_mm_pinv * H_km.transpose()));
  }
  if (k == 0) return nullptr;
  const Eigen::MatrixXd H_star = H.bottomRightCorner(k, k) - H_km * H_mm_pinv * H_km.transpose();
  const Eigen::VectorXd b_star = b.tail(k) - H_km * (H_mm_pinv * b.head(m));

  // 4. H* = S^T S (Eq. M2) and r0 (Eq. M3), keeping only informative directions.
  const Eigenspace star = SignificantEigenspace(H_star, options);
  if (star.values.size() == 0) return nullptr;
  const Eigen::MatrixXd S = star.values.cwiseSqrt().asDiagonal() * star.vectors.transpose();
  const Eigen::VectorXd r0 =
      star.values.cwiseSqrt().cwiseInverse().asDiagonal() * (star.vectors.transpose() * b_star);

  return std::make_unique<MarginalizationPrior>(std::move(kept), S, r0);
}

}  // namespace estimation
}  // namespace autocal
