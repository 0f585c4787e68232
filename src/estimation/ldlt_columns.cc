#include "estimation/ldlt_columns.h"

#include "autocal/common/error.h"

namespace autocal {
namespace estimation {
namespace internal {

RowMajorMatrix SolveColumns(const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>>& ldlt,
                            const Eigen::MatrixXd& B) {
  if (ldlt.info() != Eigen::Success) throw Error("SolveColumns: the factorization failed");
  if (B.rows() != ldlt.rows()) {
    throw Error("SolveColumns: " + std::to_string(B.rows()) + " rows for a matrix of size " +
                std::to_string(ldlt.rows()));
  }
  // P H P^T = L D L^T, L unit lower triangular, stored by columns without its diagonal.
  RowMajorMatrix X = ldlt.permutationP() * B;
  const Eigen::SparseMatrix<double>& L = ldlt.matrixL().nestedExpression();
  const Eigen::VectorXd& D = ldlt.vectorD();
  const Eigen::Index n = L.cols();
  for (Eigen::Index j = 0; j < n; ++j) {  // L Y = X: column j's entries update later rows
    for (Eigen::SparseMatrix<double>::InnerIterator it(L, j); it; ++it) {
      if (it.index() > j) X.row(it.index()) -= it.value() * X.row(j);
    }
  }
  X = D.asDiagonal().inverse() * X;
  for (Eigen::Index j = n - 1; j >= 0; --j) {  // L^T Z = Y: row j of L^T is column j of L
    for (Eigen::SparseMatrix<double>::InnerIterator it(L, j); it; ++it) {
      if (it.index() > j) X.row(j) -= it.value() * X.row(it.index());
    }
  }
  return ldlt.permutationPinv() * X;
}

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
