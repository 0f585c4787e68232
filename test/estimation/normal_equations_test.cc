#include "estimation/normal_equations.h"

#include <ceres/ceres.h>
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <random>
#include <utility>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/geometry/manifolds.h"
#include "autocal/geometry/so3.h"
#include "estimation/pose_chain.h"

namespace autocal {
namespace estimation {
namespace internal {
namespace {

// r = A x + c over the blocks' ambient values (a quaternion block's rows see its tangent through
// Ceres' manifold).
class LinearRows final : public ceres::CostFunction {
 public:
  LinearRows(Eigen::MatrixXd A, Eigen::VectorXd c, const std::vector<int>& sizes)
      : A_(std::move(A)), c_(std::move(c)) {
    set_num_residuals(static_cast<int>(A_.rows()));
    for (int size : sizes) mutable_parameter_block_sizes()->push_back(size);
  }
  bool Evaluate(double const* const* x, double* r, double** jacobians) const override {
    Eigen::VectorXd all(A_.cols());
    int column = 0;
    for (size_t k = 0; k < parameter_block_sizes().size(); ++k) {
      const int size = parameter_block_sizes()[k];
      all.segment(column, size) = Eigen::Map<const Eigen::VectorXd>(x[k], size);
      column += size;
    }
    Eigen::Map<Eigen::VectorXd>(r, num_residuals()) = A_ * all + c_;
    if (jacobians == nullptr) return true;
    column = 0;
    for (size_t k = 0; k < parameter_block_sizes().size(); ++k) {
      const int size = parameter_block_sizes()[k];
      if (jacobians[k] != nullptr) {
        Eigen::Map<RowMajorMatrix>(jacobians[k], num_residuals(), size) =
            A_.middleCols(column, size);
      }
      column += size;
    }
    return true;
  }

 private:
  Eigen::MatrixXd A_;
  Eigen::VectorXd c_;
};

// Rows over blocks of sizes 4 (a quaternion), 3, 1, 3, 4 (a quaternion), 3; a constant block.
// Few rows take the pairwise products, many rows (a prior) the stacked product: both must
// give J^T J and J^T r of the tangent Jacobian, on and below the block diagonal, in any order
// of the blocks in H.
void ExpectNormalEquations(int rows) {
  std::mt19937 rng(static_cast<uint32_t>(rows));
  std::normal_distribution<double> n(0.0, 1.0);
  const std::vector<int> sizes = {4, 3, 1, 3, 4, 3};
  std::vector<Eigen::VectorXd> values;
  for (int size : sizes) {
    Eigen::VectorXd v(size);
    for (int i = 0; i < size; ++i) v(i) = n(rng);
    if (size == 4) v.normalize();
    values.push_back(v);
  }
  int ambient = 0;
  for (int size : sizes) ambient += size;
  Eigen::MatrixXd A(rows, ambient);
  for (int i = 0; i < A.size(); ++i) A(i) = n(rng);
  Eigen::VectorXd c(rows);
  for (int i = 0; i < rows; ++i) c(i) = n(rng);

  ceres::Problem::Options problem_options;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  geometry::RightQuaternionManifold quaternion;
  std::vector<double*> blocks;
  for (size_t k = 0; k < sizes.size(); ++k) {
    blocks.push_back(values[k].data());
    problem.AddParameterBlock(blocks.back(), sizes[k], sizes[k] == 4 ? &quaternion : nullptr);
  }
  problem.SetParameterBlockConstant(blocks[2]);
  const ceres::ResidualBlockId id =
      problem.AddResidualBlock(new LinearRows(A, c, sizes), nullptr, blocks);

  // Tangent offsets in H, not in the order of the residual's blocks.
  BlockOffsets offsets;
  offsets[blocks[5]] = 0;   // 3
  offsets[blocks[0]] = 3;   // 3 (tangent of 4)
  offsets[blocks[3]] = 6;   // 3
  offsets[blocks[1]] = 9;   // 3
  offsets[blocks[4]] = 12;  // 3
  const int size = 15;
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(size, size);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(size);
  const double cost = AccumulateNormalEquations(&problem, {id}, offsets, &H, &b, "test");

  // Expected: the tangent Jacobian in H's order.
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(rows, size);
  int column = 0;
  for (size_t k = 0; k < sizes.size(); ++k) {
    const auto block = A.middleCols(column, sizes[k]);
    column += sizes[k];
    if (k == 2) continue;
    const int at = offsets.at(blocks[k]);
    if (sizes[k] == 4) {
      Eigen::Matrix<double, 4, 3, Eigen::RowMajor> plus;
      quaternion.PlusJacobian(values[k].data(), plus.data());
      J.middleCols(at, 3) = block * plus;
    } else {
      J.middleCols(at, 3) = block;
    }
  }
  Eigen::VectorXd all(ambient);
  column = 0;
  for (size_t k = 0; k < sizes.size(); ++k) {
    all.segment(column, sizes[k]) = values[k];
    column += sizes[k];
  }
  const Eigen::VectorXd r = A * all + c;
  const Eigen::MatrixXd expected = J.transpose() * J;
  H.triangularView<Eigen::StrictlyUpper>() = H.transpose();
  EXPECT_LT((H - expected).norm(), 1e-10 * expected.norm()) << rows << " rows\n" << H - expected;
  EXPECT_LT((b - J.transpose() * r).norm(), 1e-10 * b.norm()) << rows << " rows";
  EXPECT_NEAR(cost, 0.5 * r.squaredNorm(), 1e-10 * cost);
}

// weak - p_1.x, weighted 1e-5.
struct WeakRow {
  template <typename T>
  bool operator()(const T* weak, const T* p, T* residual) const {
    residual[0] = T(1e-5) * (weak[0] - p[0]);
    return true;
  }
};

TEST(AccumulateNormalEquations, PairwiseProductsForFewRows) { ExpectNormalEquations(6); }

TEST(AccumulateNormalEquations, OneStackedProductForManyRows) { ExpectNormalEquations(40); }

// ceres::Covariance's DENSE_SVD with null_space_rank -1: the oracle of DenseBlockCovariance.
Eigen::MatrixXd CeresDenseSvd(ceres::Problem* problem, const std::vector<const double*>& blocks,
                              double rcn) {
  ceres::Covariance::Options options;
  options.algorithm_type = ceres::DENSE_SVD;
  options.null_space_rank = -1;
  options.min_reciprocal_condition_number = rcn;
  ceres::Covariance covariance(options);
  std::vector<std::pair<const double*, const double*>> pairs;
  int size = 0;
  for (const double* a : blocks) {
    size += problem->ParameterBlockTangentSize(a);
    for (const double* b : blocks) pairs.emplace_back(a, b);
  }
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> out(size, size);
  if (!covariance.Compute(pairs, problem) ||
      !covariance.GetCovarianceMatrixInTangentSpace(blocks, out.data())) {
    ADD_FAILURE() << "ceres::Covariance failed";
  }
  return out;
}

// The window's covariance agrees with ceres::Covariance's DENSE_SVD (null_space_rank -1) on a
// pose chain with a robust loss, for blocks asked out of the problem's order.
TEST(DenseBlockCovariance, MatchesCeresDenseSvd) {
  const test::PoseChainProblem chain(3);
  test::PoseChain x = chain.initial_values();
  ceres::Problem problem;
  chain.Build(&problem, &x, false);
  const std::vector<const double*> blocks = {x.lever.data(), x.p[2].data(), x.q[1].coeffs().data()};
  const Eigen::MatrixXd ours = DenseBlockCovariance(&problem, blocks, 1e-14, 1, "test");

  const Eigen::MatrixXd theirs = CeresDenseSvd(&problem, blocks, 1e-14);
  ASSERT_EQ(ours.rows(), 9);
  EXPECT_LT((ours - theirs).norm(), 1e-10 * theirs.norm()) << ours << "\n\n" << theirs;
  EXPECT_GT(ours.diagonal().minCoeff(), 0.0);
}

// With a weakly determined direction and a constant block: the singular values dropped are
// those with (s / s_max)^2 below the reciprocal condition number (Ceres' rule), not s / s_max,
// and the constant block has no column.
TEST(DenseBlockCovariance, DropsWhatCeresDropsAndSkipsConstantBlocks) {
  const test::PoseChainProblem chain(5);
  test::PoseChain x = chain.initial_values();
  ceres::Problem problem;
  chain.Build(&problem, &x, false);
  // A block seen only through a row of weight 1e-5: the smallest singular value of J.
  double weak = 0.3;
  problem.AddResidualBlock(new ceres::AutoDiffCostFunction<WeakRow, 1, 1, 3>(new WeakRow), nullptr,
                           &weak, x.p[1].data());
  problem.SetParameterBlockConstant(x.p[3].data());
  // The ratio s_min / s_max of J, and a condition number between its square and itself.
  std::vector<double*> variable;
  problem.GetParameterBlocks(&variable);
  variable.erase(std::remove(variable.begin(), variable.end(), x.p[3].data()), variable.end());
  ceres::Problem::EvaluateOptions evaluate;
  evaluate.parameter_blocks = variable;
  ceres::CRSMatrix crs;
  ASSERT_TRUE(problem.Evaluate(evaluate, nullptr, nullptr, nullptr, &crs));
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(crs.num_rows, crs.num_cols);
  for (int r = 0; r < crs.num_rows; ++r) {
    for (int k = crs.rows[r]; k < crs.rows[r + 1]; ++k) J(r, crs.cols[k]) = crs.values[k];
  }
  const Eigen::VectorXd s = Eigen::JacobiSVD<Eigen::MatrixXd>(J).singularValues();
  const double ratio = s(s.size() - 1) / s(0);
  ASSERT_LT(ratio, 1e-4);
  const double rcn = std::pow(ratio, 1.5);  // ratio^2 < rcn < ratio

  const std::vector<const double*> blocks = {&weak, x.p[1].data(), x.lever.data()};
  const Eigen::MatrixXd ours = DenseBlockCovariance(&problem, blocks, rcn, 2, "test");
  const Eigen::MatrixXd theirs = CeresDenseSvd(&problem, blocks, rcn);
  EXPECT_LT((ours - theirs).norm(), 1e-8 * theirs.norm()) << ours << "\n\n" << theirs;
  // The weak direction was dropped: its variance is far below the 1e10 its row alone states.
  EXPECT_LT(ours(0, 0), 1e3);
  EXPECT_EQ(ours, ours.transpose());
  EXPECT_THROW(DenseBlockCovariance(&problem, {x.p[3].data()}, rcn, 1, "test"), Error);
}

}  // namespace
}  // namespace internal
}  // namespace estimation
}  // namespace autocal
