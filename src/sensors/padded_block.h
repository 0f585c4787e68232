#pragma once

// 3x3 matrix kernels on 4x3 blocks padded with a zero row, for the IMU preintegration's
// covariance propagation: every column is two SIMD packets, so products and transposes run
// on whole packets. Each kernel is the plain 3x3 operation on the top three rows.

#include <Eigen/Core>

namespace autocal {
namespace sensors {
namespace internal {

// A 3x3 matrix stored as 4x3 with a zero last row, so that each column is two whole SIMD
// packets.
using PaddedBlock = Eigen::Matrix<double, 4, 3>;

// Blocks are written a whole column (4-vector) at a time: a column assembled from separate
// scalar stores and read back as packets would stall store-to-load forwarding.

// Column j of *out = (x, y, z, 0), as two packets built in registers.
EIGEN_ALWAYS_INLINE void SetColumn(int j, double x, double y, double z, PaddedBlock* out) {
#ifdef EIGEN_VECTORIZE_SSE2
  double* o = out->data() + 4 * j;
  _mm_storeu_pd(o, _mm_set_pd(y, x));
  _mm_storeu_pd(o + 2, _mm_set_sd(z));
#else
  out->col(j) = Eigen::Vector4d(x, y, z, 0.0);
#endif
}

// The 3x3 matrix m as a PaddedBlock (zero last row).
inline PaddedBlock Padded(const Eigen::Matrix3d& m) {
  PaddedBlock out;
  for (int j = 0; j < 3; ++j) SetColumn(j, m(0, j), m(1, j), m(2, j), &out);
  return out;
}

// X^T.
EIGEN_ALWAYS_INLINE PaddedBlock Transposed(const PaddedBlock& X) {
  PaddedBlock out;
#ifdef EIGEN_VECTORIZE_SSE2
  // Register shuffles of the packets (x0j, x1j) and (x2j, 0) of the columns.
  const double* x = X.data();
  const __m128d top0 = _mm_loadu_pd(x), top1 = _mm_loadu_pd(x + 4), top2 = _mm_loadu_pd(x + 8);
  const __m128d low0 = _mm_loadu_pd(x + 2), low1 = _mm_loadu_pd(x + 6);
  const __m128d zero = _mm_setzero_pd();
  double* o = out.data();
  _mm_storeu_pd(o, _mm_unpacklo_pd(top0, top1));      // (x00, x01)
  _mm_storeu_pd(o + 2, _mm_unpacklo_pd(top2, zero));  // (x02, 0)
  _mm_storeu_pd(o + 4, _mm_unpackhi_pd(top0, top1));  // (x10, x11)
  _mm_storeu_pd(o + 6, _mm_unpackhi_pd(top2, zero));  // (x12, 0)
  _mm_storeu_pd(o + 8, _mm_unpacklo_pd(low0, low1));  // (x20, x21)
  _mm_storeu_pd(o + 10, _mm_loadu_pd(x + 10));        // (x22, 0)
#else
  for (int j = 0; j < 3; ++j) SetColumn(j, X(j, 0), X(j, 1), X(j, 2), &out);
#endif
  return out;
}

// X Y^T as column combinations of X: column j is sum_k X_k Y(j, k).
EIGEN_ALWAYS_INLINE PaddedBlock TimesTransposed(const PaddedBlock& X, const PaddedBlock& Y) {
  PaddedBlock out;
  out.col(0) = X.col(0) * Y(0, 0) + X.col(1) * Y(0, 1) + X.col(2) * Y(0, 2);
  out.col(1) = X.col(0) * Y(1, 0) + X.col(1) * Y(1, 1) + X.col(2) * Y(1, 2);
  out.col(2) = X.col(0) * Y(2, 0) + X.col(1) * Y(2, 1) + X.col(2) * Y(2, 2);
  return out;
}

// X Hat(a), column by column: row r of the product is (r x a)^T. A third fewer operations
// than the dense product with the skew matrix.
EIGEN_ALWAYS_INLINE PaddedBlock TimesHat(const PaddedBlock& X, const Eigen::Vector3d& a) {
  PaddedBlock out;
  out.col(0) = a.z() * X.col(1) - a.y() * X.col(2);
  out.col(1) = a.x() * X.col(2) - a.z() * X.col(0);
  out.col(2) = a.y() * X.col(0) - a.x() * X.col(1);
  return out;
}

// -Hat(a) X: column j is x_j x a, as a PaddedBlock (Rows = 4) or a plain 3x3 matrix (Rows = 3).
// It mixes rows, so it does not vectorize; the propagation uses it only where no
// transposed form is at hand.
template <int Rows>
inline Eigen::Matrix<double, Rows, 3> MinusHatTimes(const Eigen::Vector3d& a,
                                                    const PaddedBlock& X) {
  Eigen::Matrix<double, Rows, 3> out;
  for (int j = 0; j < 3; ++j) {
    const Eigen::Vector3d c = X.col(j).head<3>().cross(a);
    if constexpr (Rows == 4) {
      SetColumn(j, c.x(), c.y(), c.z(), &out);
    } else {
      out.col(j) = c;
    }
  }
  return out;
}

}  // namespace internal
}  // namespace sensors
}  // namespace autocal
