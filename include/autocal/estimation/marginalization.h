#pragma once

// Marginalization of parameter blocks out of a Ceres problem into a linear prior
// (docs/estimation.md, "Marginalization").
//
// All residual blocks touching the blocks to drop are linearized at the current values
// (robust losses applied, Jacobians in the tangent space), stacked into the Gauss-Newton
// system H dx = -b, and the dropped blocks are removed by the Schur complement
//   H* = H_kk - H_km H_mm^+ H_mk,   b* = b_k - H_km H_mm^+ b_m      (Eq. M1)
// with H_mm^+ a pseudo-inverse that ignores directions without information, so rank-deficient
// blocks (e.g. unobservable calibration directions) are safe. H* is factored as S^T S with
// S = sqrt(L) V^T from its eigen-decomposition (Eq. M2), giving the prior residual
//   r(x) = S (x [-] x0) + r0,   r0 = sqrt(L)^-1 V^T b*               (Eq. M3)
// over the kept blocks, where x0 are their values at marginalization (first estimates: the
// prior never re-linearizes) and [-] is the manifold's Minus.
//
// The same system also gives the marginalized blocks given the kept ones, the Gaussian
// conditional mean
//   dx_m = -H_mm^+ (b_m + H_mk dx_k)                                    (Eq. M4)
// which a smoother applies backwards once later estimates of the kept blocks are known
// (docs/estimation.md, "Smoothing").

#include <ceres/ceres.h>

#include <Eigen/Core>
#include <memory>
#include <vector>

namespace autocal {
namespace estimation {

struct MarginalizationOptions {
  // Eigenvalues of H_mm and H* below this fraction of the largest are treated as zero.
  double relative_eigenvalue_threshold = 1e-10;
  // Eigenvalues below this absolute value are treated as zero as well.
  double absolute_eigenvalue_threshold = 1e-12;
};

// One kept parameter block of a prior: where it lives, its sizes and its manifold
// (nullptr = Euclidean). Supported manifolds: none and geometry::RightQuaternionManifold.
struct PriorBlock {
  double* values = nullptr;
  int ambient_size = 0;
  int tangent_size = 0;
  const ceres::Manifold* manifold = nullptr;
};

// The linear prior left by marginalization (Eq. M3). Parameter blocks: the kept blocks in the
// order of blocks().
class MarginalizationPrior final : public ceres::CostFunction {
 public:
  MarginalizationPrior(std::vector<PriorBlock> blocks, Eigen::MatrixXd sqrt_information,
                       Eigen::VectorXd r0);

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

  const std::vector<PriorBlock>& blocks() const { return blocks_; }
  // Pointers to the kept blocks, for Problem::AddResidualBlock.
  std::vector<double*> parameter_pointers() const;
  const Eigen::MatrixXd& sqrt_information() const { return sqrt_information_; }

 private:
  std::vector<PriorBlock> blocks_;
  std::vector<Eigen::VectorXd> x0_;  // linearization values (ambient)
  std::vector<int> tangent_offsets_;
  Eigen::MatrixXd sqrt_information_;
  Eigen::VectorXd r0_;
};

// The marginalized blocks as a function of the kept ones (Eq. M4), linearized at the values
// both had at marginalization. It copies those values; the blocks' `values` pointers only
// say which blocks they were (they may dangle later), and the manifolds must outlive it.
class MarginalConditional {
 public:
  MarginalConditional() = default;
  MarginalConditional(std::vector<PriorBlock> marginalized, std::vector<PriorBlock> kept,
                      Eigen::VectorXd offset, Eigen::MatrixXd gain);

  // Marginalized blocks in the order given to Marginalize, without constant ones; kept blocks
  // in the order of the prior's blocks().
  const std::vector<PriorBlock>& marginalized_blocks() const { return marginalized_; }
  const std::vector<PriorBlock>& kept_blocks() const { return kept_; }
  // dx_m = offset + gain dx_k (tangent coordinates).
  const Eigen::VectorXd& offset() const { return offset_; }
  const Eigen::MatrixXd& gain() const { return gain_; }

  // Writes x_m0 [+] (offset + gain (x_k [-] x_k0)) to `marginalized_out` given values of the
  // kept blocks (ambient, in the order of kept_blocks()). Throws autocal::Error on a count
  // mismatch or a non-finite result.
  void Apply(const std::vector<const double*>& kept_values,
             const std::vector<double*>& marginalized_out) const;

 private:
  std::vector<PriorBlock> marginalized_;
  std::vector<PriorBlock> kept_;
  std::vector<Eigen::VectorXd> marginalized_x0_;
  std::vector<Eigen::VectorXd> kept_x0_;
  Eigen::VectorXd offset_;
  Eigen::MatrixXd gain_;
};

// Linearizes every residual block of `problem` that touches one of `to_marginalize` and
// returns the prior on the other blocks those residuals touch (nullptr when they touch no
// other block). Does not modify the problem: the caller removes the marginalized blocks
// (Problem::RemoveParameterBlock also removes their residuals) and adds the prior with
// AddResidualBlock(prior, nullptr, prior->parameter_pointers()). With `conditional`, also
// returns Eq. M4 there (its kept blocks are the prior's, also when the prior is nullptr
// because the kept blocks got no information).
std::unique_ptr<MarginalizationPrior> Marginalize(ceres::Problem* problem,
                                                  const std::vector<double*>& to_marginalize,
                                                  const MarginalizationOptions& options = {},
                                                  MarginalConditional* conditional = nullptr);

}  // namespace estimation
}  // namespace autocal
