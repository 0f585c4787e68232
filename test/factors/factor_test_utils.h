#pragma once

// Shared checks for cost functions: GradientChecker with the blocks' manifolds, and
// analytic-vs-autodiff agreement on the tangent spaces.

#include <ceres/ceres.h>
#include <ceres/gradient_checker.h>
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <string>
#include <vector>

namespace autocal {
namespace test {

using RowMajorMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// Residual and per-block ambient Jacobians of a cost function at the given blocks.
struct Evaluation {
  Eigen::VectorXd residual;
  std::vector<RowMajorMatrix> jacobians;
};

inline Evaluation Evaluate(const ceres::CostFunction& cost, const std::vector<double*>& blocks) {
  Evaluation out;
  const int n = cost.num_residuals();
  out.residual.resize(n);
  std::vector<double*> jacobian_ptrs;
  for (int size : cost.parameter_block_sizes()) {
    out.jacobians.emplace_back(n, size);
  }
  for (auto& j : out.jacobians) jacobian_ptrs.push_back(j.data());
  EXPECT_TRUE(cost.Evaluate(blocks.data(), out.residual.data(), jacobian_ptrs.data()));
  return out;
}

// Ceres' GradientChecker (numeric differences in the ambient coordinates, projected with
// the manifolds' PlusJacobian; nullptr for a Euclidean block) must agree with the analytic
// Jacobians on every tangent block, measured as ||J - J_numeric|| <= relative_precision *
// ||J_numeric||. Its finite differences carry a truncation error of ~1e-5 relative on the
// strongly curved whitened rotation residuals, so it is the coarse oracle; the autodiff twin
// (ExpectSameJacobians, 1e-9) is the tight one. The checker's own per-entry test is not
// used: it flags near-zero entries whose absolute finite-difference noise is set by the
// block's largest entries.
//
// The checker differentiates with Ridders' method, whose first step is 1 % of each parameter
// (ridders_relative_initial_step_size): 0.5 m on a 50 m position. A robustified residual
// bends within a sigma (centimetres), so its checks pass `options` with a smaller first step.
inline void ExpectGradientCheckPasses(const ceres::CostFunction& cost,
                                      const std::vector<const ceres::Manifold*>& manifolds,
                                      const std::vector<double*>& blocks, double relative_precision,
                                      const std::string& context,
                                      const ceres::NumericDiffOptions& options = {}) {
  ceres::GradientChecker checker(&cost, &manifolds, options);
  ceres::GradientChecker::ProbeResults results;
  checker.Probe(blocks.data(), relative_precision, &results);
  ASSERT_TRUE(results.return_value) << context << ": cost function failed";
  ASSERT_EQ(results.local_jacobians.size(), blocks.size());
  for (size_t k = 0; k < blocks.size(); ++k) {
    const ceres::Matrix& analytic = results.local_jacobians[k];
    const ceres::Matrix& numeric = results.local_numeric_jacobians[k];
    EXPECT_LE((analytic - numeric).norm(), relative_precision * std::max(1.0, numeric.norm()))
        << context << ", block " << k << "\nanalytic:\n"
        << analytic << "\nnumeric:\n"
        << numeric;
  }
}

// Central differences through the manifolds' Plus (step h on each tangent coordinate)
// against the analytic tangent Jacobians: a second, tighter numeric oracle (truncation
// O(h^2)).
inline void ExpectCentralDifferencesMatch(const ceres::CostFunction& cost,
                                          const std::vector<const ceres::Manifold*>& manifolds,
                                          const std::vector<double*>& blocks, double step,
                                          double relative_tolerance, const std::string& context) {
  const Evaluation analytic = Evaluate(cost, blocks);
  const int n = cost.num_residuals();
  for (size_t k = 0; k < blocks.size(); ++k) {
    const int ambient = cost.parameter_block_sizes()[k];
    const int tangent = manifolds[k] != nullptr ? manifolds[k]->TangentSize() : ambient;
    RowMajorMatrix j_analytic = analytic.jacobians[k];
    if (manifolds[k] != nullptr) {
      RowMajorMatrix plus(ambient, tangent);
      manifolds[k]->PlusJacobian(blocks[k], plus.data());
      j_analytic = j_analytic * plus;
    }
    const Eigen::VectorXd x0 = Eigen::Map<const Eigen::VectorXd>(blocks[k], ambient);
    RowMajorMatrix j_numeric(n, tangent);
    for (int c = 0; c < tangent; ++c) {
      Eigen::VectorXd residual[2];
      for (int side = 0; side < 2; ++side) {
        Eigen::VectorXd delta = Eigen::VectorXd::Zero(tangent);
        delta(c) = side == 0 ? step : -step;
        Eigen::Map<Eigen::VectorXd> x(blocks[k], ambient);
        if (manifolds[k] != nullptr) {
          Eigen::VectorXd moved(ambient);
          manifolds[k]->Plus(x0.data(), delta.data(), moved.data());
          x = moved;
        } else {
          x = x0 + delta;
        }
        residual[side].resize(n);
        EXPECT_TRUE(cost.Evaluate(blocks.data(), residual[side].data(), nullptr));
        x = x0;
      }
      j_numeric.col(c) = (residual[0] - residual[1]) / (2.0 * step);
    }
    EXPECT_LE((j_analytic - j_numeric).norm(), relative_tolerance * std::max(1.0, j_numeric.norm()))
        << context << ", block " << k << "\nanalytic:\n"
        << j_analytic << "\ncentral differences:\n"
        << j_numeric;
  }
}

// Analytic and autodiff cost functions agree on the residual and on every Jacobian,
// compared on the tangent space (ambient Jacobian times the manifold's PlusJacobian).
inline void ExpectSameJacobians(const ceres::CostFunction& analytic,
                                const ceres::CostFunction& autodiff,
                                const std::vector<const ceres::Manifold*>& manifolds,
                                const std::vector<double*>& blocks, double relative_tolerance,
                                const std::string& context) {
  const Evaluation a = Evaluate(analytic, blocks);
  const Evaluation b = Evaluate(autodiff, blocks);
  EXPECT_LE((a.residual - b.residual).norm(), relative_tolerance * (1.0 + b.residual.norm()))
      << context << "\nanalytic: " << a.residual.transpose()
      << "\nautodiff: " << b.residual.transpose();
  for (size_t k = 0; k < blocks.size(); ++k) {
    RowMajorMatrix ja = a.jacobians[k], jb = b.jacobians[k];
    if (manifolds[k] != nullptr) {
      RowMajorMatrix plus(manifolds[k]->AmbientSize(), manifolds[k]->TangentSize());
      manifolds[k]->PlusJacobian(blocks[k], plus.data());
      ja = ja * plus;
      jb = jb * plus;
    }
    EXPECT_LE((ja - jb).norm(), relative_tolerance * std::max(1.0, jb.norm()))
        << context << ", block " << k << "\nanalytic:\n"
        << ja << "\nautodiff:\n"
        << jb;
  }
}

}  // namespace test
}  // namespace autocal
