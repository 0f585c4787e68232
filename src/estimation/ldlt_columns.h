#pragma once

// H^-1 B for many right-hand sides at once, from Eigen's sparse LDL^T of H. Eigen's own solve
// walks the factor once per column of B; for the calibration's covariance (a column per
// estimated direction through the factor of a long log's normal equations, tens of megabytes)
// each walk misses the cache. Here B is held by rows and the factor walked once forward and
// once backward, each of its entries applied to a whole row. Every column's sums run in the
// order of Eigen's solve, so the result has the same bits (docs/calibration.md, "Speed").

#include <Eigen/Core>
#include <Eigen/SparseCore>

namespace autocal {
namespace estimation {
namespace internal {

using RowMajorMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// X with L D L^T X = B for a unit lower triangular L stored by columns without its diagonal
// (Eigen::SimplicialLDLT's matrixL() and vectorD()); B has L's size in rows. The permutation of
// the factorization, if any, is the caller's: H^-1 B = P^T SolveColumns(L, D, P B) for
// P H P^T = L D L^T.
RowMajorMatrix SolveColumns(const Eigen::SparseMatrix<double>& L, const Eigen::VectorXd& D,
                            const Eigen::MatrixXd& B);

// W with L W = B, for B^T H^-1 B = W^T D^-1 W (P B for a permuted factorization). A row of B
// that no earlier row reaches stays zero and costs nothing: for a B nonzero on the rows of one
// stretch of a log, the walk touches only the factor's columns those rows reach.
RowMajorMatrix ForwardColumns(const Eigen::SparseMatrix<double>& L, const Eigen::MatrixXd& B);

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
