#include "autocal/geometry/manifolds.h"

#include <Eigen/Geometry>
#include <cmath>

#include "autocal/geometry/quaternion_plus.h"
#include "autocal/geometry/so3.h"

namespace autocal {
namespace geometry {

namespace {
using ConstQuaternionMap = Eigen::Map<const Eigen::Quaterniond>;
}  // namespace

bool RightQuaternionManifold::Plus(const double* x, const double* delta,
                                   double* x_plus_delta) const {
  const Eigen::Map<const Eigen::Vector3d> d(delta);
  Eigen::Map<Eigen::Quaterniond> out(x_plus_delta);
  out = QuaternionPlus(ConstQuaternionMap(x), d);
  return true;
}

// d(q * Exp(delta))/d(delta) at 0 = 0.5 * [qw I + Hat(qv); -qv^T] (rows x, y, z, w).
bool RightQuaternionManifold::PlusJacobian(const double* x, double* jacobian) const {
  const ConstQuaternionMap q(x);
  Eigen::Map<Eigen::Matrix<double, 4, 3, Eigen::RowMajor>> j(jacobian);
  j.topRows<3>() = 0.5 * (q.w() * Eigen::Matrix3d::Identity() + Hat(q.vec()));
  j.bottomRows<1>() = -0.5 * q.vec().transpose();
  return true;
}

// Unlike Log(), Minus keeps the quaternion's sign (angles up to 2 pi) so that
// Plus(x, Minus(y, x)) reproduces y itself and not -y, as Ceres requires.
bool RightQuaternionManifold::Minus(const double* y, const double* x, double* y_minus_x) const {
  const Eigen::Quaterniond q = ConstQuaternionMap(x).conjugate() * ConstQuaternionMap(y);
  const double v_sq = q.vec().squaredNorm();
  Eigen::Map<Eigen::Vector3d> out(y_minus_x);
  if (v_sq < kSmallAngleSquared && q.w() > 0.0) {
    out = Log(q);
  } else if (v_sq == 0.0) {
    out.setZero();  // q = -identity: a 2 pi turn, equivalent to no rotation
  } else {
    const double v_norm = std::sqrt(v_sq);
    out = (2.0 * std::atan2(v_norm, q.w()) / v_norm) * q.vec();
  }
  return true;
}

bool RightQuaternionManifold::MinusJacobian(const double* x, double* jacobian) const {
  Eigen::Map<Eigen::Matrix<double, 3, 4, Eigen::RowMajor>> j(jacobian);
  j = QuaternionMinusJacobian(x);
  return true;
}

// d Log(x^-1 * y)/dy at y = x = 2 * [xw I - Hat(xv), -xv]; the pseudo-inverse of the
// PlusJacobian for unit x.
Eigen::Matrix<double, 3, 4, Eigen::RowMajor> QuaternionMinusJacobian(const double* q_xyzw) {
  const ConstQuaternionMap q(q_xyzw);
  Eigen::Matrix<double, 3, 4, Eigen::RowMajor> j;
  j.leftCols<3>() = 2.0 * (q.w() * Eigen::Matrix3d::Identity() - Hat(q.vec()));
  j.rightCols<1>() = -2.0 * q.vec();
  return j;
}

}  // namespace geometry
}  // namespace autocal
