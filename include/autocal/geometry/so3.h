#pragma once

// SO(3) helpers templated on the scalar so that they work with double and ceres::Jet.
//
// Conventions (docs/design.md): Hamilton quaternions stored as Eigen stores them,
// [x, y, z, w]; rotation vectors phi = theta * axis; Exp/Log map between so(3) and SO(3);
// the right Jacobian Jr satisfies Exp(phi + dphi) ~= Exp(phi) * Exp(Jr(phi) * dphi)
// (Forster et al. 2017, eq. 7). Every function is safe near theta = 0 and theta = pi.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>

namespace autocal {
namespace geometry {

template <typename T>
using Vector3 = Eigen::Matrix<T, 3, 1>;
template <typename T>
using Matrix3 = Eigen::Matrix<T, 3, 3>;

// Below this squared angle the closed forms lose precision and Taylor series are used.
constexpr double kSmallAngleSquared = 1e-10;

// Skew-symmetric matrix: Hat(a) * b == a.cross(b).
template <typename Derived>
Matrix3<typename Derived::Scalar> Hat(const Eigen::MatrixBase<Derived>& v) {
  using T = typename Derived::Scalar;
  Matrix3<T> m;
  m << T(0), -v(2), v(1),  //
      v(2), T(0), -v(0),   //
      -v(1), v(0), T(0);
  return m;
}

// Inverse of Hat; reads the skew part of m (m need not be exactly skew).
template <typename Derived>
Vector3<typename Derived::Scalar> Vee(const Eigen::MatrixBase<Derived>& m) {
  using T = typename Derived::Scalar;
  return Vector3<T>(T(0.5) * (m(2, 1) - m(1, 2)), T(0.5) * (m(0, 2) - m(2, 0)),
                    T(0.5) * (m(1, 0) - m(0, 1)));
}

// Exp: rotation vector -> unit quaternion.
template <typename Derived>
Eigen::Quaternion<typename Derived::Scalar> Exp(const Eigen::MatrixBase<Derived>& phi) {
  using std::cos;
  using std::sin;
  using std::sqrt;
  using T = typename Derived::Scalar;
  const T theta_sq = phi.squaredNorm();
  T w;
  T k;  // sin(theta/2) / theta
  if (theta_sq < T(kSmallAngleSquared)) {
    w = T(1) - theta_sq / T(8);
    k = T(0.5) - theta_sq / T(48);
  } else {
    const T theta = sqrt(theta_sq);
    const T half = T(0.5) * theta;
    w = cos(half);
    k = sin(half) / theta;
  }
  Eigen::Quaternion<T> q(w, k * phi(0), k * phi(1), k * phi(2));
  return q;
}

// Log: unit quaternion -> rotation vector with angle in [0, pi]. q and -q give the same
// result. Accurate near 0 (series) and near pi (atan2, no acos).
template <typename T>
Vector3<T> Log(const Eigen::Quaternion<T>& q_in) {
  using std::atan2;
  using std::sqrt;
  Eigen::Quaternion<T> q = q_in;
  if (q.w() < T(0)) q.coeffs() = -q.coeffs();
  const Vector3<T> v = q.vec();
  const T v_sq = v.squaredNorm();
  const T w = q.w();
  T k;  // theta / sin(theta/2)
  if (v_sq < T(kSmallAngleSquared)) {
    // theta = 2 atan(|v| / w) ~= 2|v|/w (1 - |v|^2 / (3 w^2)).
    k = T(2) / w - T(2) * v_sq / (T(3) * w * w * w);
  } else {
    const T v_norm = sqrt(v_sq);
    k = T(2) * atan2(v_norm, w) / v_norm;
  }
  return k * v;
}

// Rotation matrix of a rotation vector (Rodrigues).
template <typename Derived>
Matrix3<typename Derived::Scalar> ExpMatrix(const Eigen::MatrixBase<Derived>& phi) {
  return Exp(phi).toRotationMatrix();
}

// Rotation vector of a rotation matrix.
template <typename Derived>
Vector3<typename Derived::Scalar> LogMatrix(const Eigen::MatrixBase<Derived>& R) {
  using T = typename Derived::Scalar;
  const Matrix3<T> m = R;
  return Log(Eigen::Quaternion<T>(m));
}

// Aliases with the names used in file formats and tools.
template <typename Derived>
Eigen::Quaternion<typename Derived::Scalar> RotationVectorToQuaternion(
    const Eigen::MatrixBase<Derived>& phi) {
  return Exp(phi);
}
template <typename T>
Vector3<T> QuaternionToRotationVector(const Eigen::Quaternion<T>& q) {
  return Log(q);
}

namespace internal {
// Coefficients a = (1 - cos t) / t^2 and b = (t - sin t) / t^3, with their series near 0.
template <typename T>
void JacobianCoefficients(const T& theta_sq, T* a, T* b) {
  using std::cos;
  using std::sin;
  using std::sqrt;
  if (theta_sq < T(1e-6)) {
    *a = T(0.5) - theta_sq / T(24) + theta_sq * theta_sq / T(720);
    *b = T(1.0 / 6.0) - theta_sq / T(120) + theta_sq * theta_sq / T(5040);
  } else {
    const T theta = sqrt(theta_sq);
    *a = (T(1) - cos(theta)) / theta_sq;
    *b = (theta - sin(theta)) / (theta_sq * theta);
  }
}
}  // namespace internal

// Right Jacobian of SO(3): Jr(phi) = I - a Hat(phi) + b Hat(phi)^2.
template <typename Derived>
Matrix3<typename Derived::Scalar> RightJacobian(const Eigen::MatrixBase<Derived>& phi) {
  using T = typename Derived::Scalar;
  T a, b;
  internal::JacobianCoefficients(T(phi.squaredNorm()), &a, &b);
  const Matrix3<T> W = Hat(phi);
  return Matrix3<T>::Identity() - a * W + b * W * W;
}

// Left Jacobian: Jl(phi) = Jr(-phi) = I + a Hat(phi) + b Hat(phi)^2.
template <typename Derived>
Matrix3<typename Derived::Scalar> LeftJacobian(const Eigen::MatrixBase<Derived>& phi) {
  using T = typename Derived::Scalar;
  T a, b;
  internal::JacobianCoefficients(T(phi.squaredNorm()), &a, &b);
  const Matrix3<T> W = Hat(phi);
  return Matrix3<T>::Identity() + a * W + b * W * W;
}

// Inverse right Jacobian: Jr^-1(phi) = I + 1/2 Hat(phi) + c Hat(phi)^2 with
// c = 1/t^2 - cot(t/2) / (2 t). Finite up to (not including) theta = 2 pi.
template <typename Derived>
Matrix3<typename Derived::Scalar> RightJacobianInverse(const Eigen::MatrixBase<Derived>& phi) {
  using std::cos;
  using std::sin;
  using std::sqrt;
  using T = typename Derived::Scalar;
  const T theta_sq = phi.squaredNorm();
  T c;
  if (theta_sq < T(1e-6)) {
    c = T(1.0 / 12.0) + theta_sq / T(720) + theta_sq * theta_sq / T(30240);
  } else {
    const T theta = sqrt(theta_sq);
    const T half = T(0.5) * theta;
    c = T(1) / theta_sq - cos(half) / (T(2) * theta * sin(half));
  }
  const Matrix3<T> W = Hat(phi);
  return Matrix3<T>::Identity() + T(0.5) * W + c * W * W;
}

// Inverse left Jacobian: Jl^-1(phi) = Jr^-1(-phi).
template <typename Derived>
Matrix3<typename Derived::Scalar> LeftJacobianInverse(const Eigen::MatrixBase<Derived>& phi) {
  using T = typename Derived::Scalar;
  const Vector3<T> minus_phi = -phi;
  return RightJacobianInverse(minus_phi);
}

// Rotation angle of q in [0, pi], radians.
template <typename T>
T AngleOf(const Eigen::Quaternion<T>& q) {
  return Log(q).norm();
}

// Angle of the relative rotation a^-1 * b, radians.
template <typename T>
T AngularDistance(const Eigen::Quaternion<T>& a, const Eigen::Quaternion<T>& b) {
  return AngleOf(Eigen::Quaternion<T>(a.conjugate() * b));
}

}  // namespace geometry
}  // namespace autocal
