#include "estimation/ldlt_columns.h"

#include <gtest/gtest.h>

#include <Eigen/SparseCholesky>
#include <random>
#include <vector>

#include "autocal/common/error.h"

namespace autocal {
namespace estimation {
namespace internal {
namespace {

// A banded symmetric positive definite matrix with a few dense rows and columns, the shape
// of a calibration's normal equations: keyframes coupled to their neighbours, the calibration
// to every keyframe.
Eigen::SparseMatrix<double> BandedWithDenseCorner(int n, int band, int dense, std::mt19937* rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Eigen::Triplet<double>> entries;
  for (int i = 0; i < n; ++i) {
    entries.emplace_back(i, i, 2.0 * (band + dense) + 1.0);
    for (int j = std::max(0, i - band); j < i; ++j) entries.emplace_back(i, j, u(*rng));
    if (i >= n - dense) {
      for (int j = 0; j < i - band; ++j) entries.emplace_back(i, j, 0.1 * u(*rng));
    }
  }
  Eigen::SparseMatrix<double> lower(n, n);
  lower.setFromTriplets(entries.begin(), entries.end());
  return Eigen::SparseMatrix<double>(lower.selfadjointView<Eigen::Lower>());
}

// H^-1 B = P^T SolveColumns(L, D, P B) for Eigen's P H P^T = L D L^T.
RowMajorMatrix Solve(const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>>& ldlt,
                     const Eigen::MatrixXd& B) {
  const Eigen::MatrixXd permuted = ldlt.permutationP() * B;
  return ldlt.permutationPinv() *
         SolveColumns(ldlt.matrixL().nestedExpression(), ldlt.vectorD(), permuted);
}

TEST(SolveColumns, GivesTheBitsOfEigensSolve) {
  std::mt19937 rng(7);
  const Eigen::SparseMatrix<double> H = BandedWithDenseCorner(400, 12, 9, &rng);
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(H);
  ASSERT_EQ(ldlt.info(), Eigen::Success);
  Eigen::MatrixXd B = Eigen::MatrixXd::Zero(H.rows(), 30);
  for (int c = 0; c < 30; ++c) B(H.rows() - 30 + c, c) = 1.0;  // unit columns, as the covariance
  B.col(3).setRandom();
  const Eigen::MatrixXd expected = ldlt.solve(B);
  const RowMajorMatrix X = Solve(ldlt, B);
  ASSERT_EQ(X.rows(), expected.rows());
  ASSERT_EQ(X.cols(), expected.cols());
  for (int r = 0; r < X.rows(); ++r) {
    for (int c = 0; c < X.cols(); ++c) ASSERT_EQ(X(r, c), expected(r, c)) << r << ", " << c;
  }
  // And it solves: H X = B.
  EXPECT_LT((H * Eigen::MatrixXd(X) - B).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(SolveColumns, HandlesOneByOneAndNoColumns) {
  Eigen::SparseMatrix<double> H(1, 1);
  H.insert(0, 0) = 4.0;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(H);
  EXPECT_EQ(Solve(ldlt, Eigen::MatrixXd::Constant(1, 2, 2.0)), RowMajorMatrix::Constant(1, 2, 0.5));
  EXPECT_EQ(Solve(ldlt, Eigen::MatrixXd(1, 0)).cols(), 0);
}

TEST(SolveColumns, RefusesMismatchedSizes) {
  Eigen::SparseMatrix<double> L(2, 2);
  EXPECT_THROW(SolveColumns(L, Eigen::VectorXd::Ones(2), Eigen::MatrixXd::Zero(3, 1)), Error);
  EXPECT_THROW(SolveColumns(L, Eigen::VectorXd::Ones(3), Eigen::MatrixXd::Zero(2, 1)), Error);
  EXPECT_THROW(SolveColumns(Eigen::SparseMatrix<double>(2, 3), Eigen::VectorXd::Ones(2),
                            Eigen::MatrixXd::Zero(2, 1)),
               Error);
}

// B^T H^-1 B = W^T D^-1 W for W = ForwardColumns(L, P B), with B nonzero on a band of rows in
// the middle (one stretch of a log) and on the dense corner.
TEST(ForwardColumns, GivesTheQuadraticFormOfTheInverse) {
  std::mt19937 rng(11);
  const Eigen::SparseMatrix<double> H = BandedWithDenseCorner(400, 12, 9, &rng);
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(H);
  ASSERT_EQ(ldlt.info(), Eigen::Success);
  Eigen::MatrixXd B = Eigen::MatrixXd::Zero(H.rows(), 5);
  B.middleRows(150, 40).setRandom();
  B.bottomRows(9).setRandom();
  const Eigen::MatrixXd permuted = ldlt.permutationP() * B;
  const RowMajorMatrix W = ForwardColumns(ldlt.matrixL().nestedExpression(), permuted);
  const Eigen::MatrixXd form = W.transpose() * ldlt.vectorD().asDiagonal().inverse() * W;
  const Eigen::MatrixXd expected = B.transpose() * ldlt.solve(B);
  EXPECT_LT((form - expected).cwiseAbs().maxCoeff(), 1e-12 * expected.cwiseAbs().maxCoeff());
  EXPECT_THROW(ForwardColumns(ldlt.matrixL().nestedExpression(), Eigen::MatrixXd::Zero(3, 1)),
               Error);
}

}  // namespace
}  // namespace internal
}  // namespace estimation
}  // namespace autocal
