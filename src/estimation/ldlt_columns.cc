#include "estimation/ldlt_columns.h"

#include "autocal/common/error.h"

namespace autocal {
namespace estimation {
namespace internal {

RowMajorMatrix SolveColumns(const Eigen::SparseMatrix<double>& L, const Eigen::VectorXd& D,
                            const Eigen::MatrixXd& B) {
  if (L.rows() != L.cols() || D.size() != L.cols() || B.rows() != L.rows()) {
    throw Error("SolveColumns: a factor of size " + std::to_string(L.rows()) + " x " +
                std::to_string(L.cols()) + ", " + std::to_string(D.size()) + " pivots and " +
                std::to_string(B.rows()) + " rows of right-hand sides");
  }
  RowMajorMatrix X = B;
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
  return X;
}

RowMajorMatrix ForwardColumns(const Eigen::SparseMatrix<double>& L, const Eigen::MatrixXd& B) {
  if (L.rows() != L.cols() || B.rows() != L.rows()) {
    throw Error("ForwardColumns: a factor of size " + std::to_string(L.rows()) + " x " +
                std::to_string(L.cols()) + " and " + std::to_string(B.rows()) +
                " rows of right-hand sides");
  }
  RowMajorMatrix X = B;
  for (Eigen::Index j = 0; j < L.cols(); ++j) {
    if (X.row(j).isZero(0.0)) continue;
    for (Eigen::SparseMatrix<double>::InnerIterator it(L, j); it; ++it) {
      if (it.index() > j) X.row(it.index()) -= it.value() * X.row(j);
    }
  }
  return X;
}

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
