#pragma once

// Rigid transforms as (quaternion, translation), templated on the scalar.
// A Pose<T> named T_a_b maps points from frame b into frame a: p_a = T_a_b * p_b.
// The SE(3) tangent vector is xi = [rho; phi] (translation part first), with
// Exp(xi) = (Exp(phi), Jl(phi) * rho).

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "autocal/geometry/so3.h"

namespace autocal {
namespace geometry {

template <typename T>
using Vector6 = Eigen::Matrix<T, 6, 1>;

template <typename T>
struct Pose {
  Eigen::Quaternion<T> q = Eigen::Quaternion<T>::Identity();
  Vector3<T> p = Vector3<T>::Zero();

  Pose() = default;
  Pose(const Eigen::Quaternion<T>& rotation, const Vector3<T>& translation)
      : q(rotation), p(translation) {}

  static Pose Identity() { return Pose(); }

  // From a 4x4 homogeneous matrix (the rotation block is re-orthonormalized through the
  // quaternion).
  static Pose FromMatrix(const Eigen::Matrix<T, 4, 4>& m) {
    const Matrix3<T> R = m.template topLeftCorner<3, 3>();
    return Pose(Eigen::Quaternion<T>(R).normalized(), m.template topRightCorner<3, 1>());
  }

  Eigen::Matrix<T, 4, 4> Matrix() const {
    Eigen::Matrix<T, 4, 4> m = Eigen::Matrix<T, 4, 4>::Identity();
    m.template topLeftCorner<3, 3>() = q.toRotationMatrix();
    m.template topRightCorner<3, 1>() = p;
    return m;
  }

  Matrix3<T> R() const { return q.toRotationMatrix(); }

  Pose Inverse() const {
    const Eigen::Quaternion<T> q_inv = q.conjugate();
    return Pose(q_inv, -(q_inv * p));
  }

  // Composition: T_a_c = T_a_b * T_b_c.
  Pose operator*(const Pose& other) const { return Pose(q * other.q, q * other.p + p); }

  // Point transform: p_a = T_a_b * p_b.
  Vector3<T> operator*(const Vector3<T>& point) const { return q * point + p; }

  template <typename U>
  Pose<U> cast() const {
    return Pose<U>(q.template cast<U>(), p.template cast<U>());
  }
};

using Pose3d = Pose<double>;

// SE(3) exponential of xi = [rho; phi].
template <typename T>
Pose<T> ExpSE3(const Vector6<T>& xi) {
  const Vector3<T> rho = xi.template head<3>();
  const Vector3<T> phi = xi.template tail<3>();
  return Pose<T>(Exp(phi), LeftJacobian(phi) * rho);
}

// SE(3) logarithm, inverse of ExpSE3 for rotation angles below pi.
template <typename T>
Vector6<T> LogSE3(const Pose<T>& pose) {
  const Vector3<T> phi = Log(pose.q);
  Vector6<T> xi;
  xi.template head<3>() = LeftJacobianInverse(phi) * pose.p;
  xi.template tail<3>() = phi;
  return xi;
}

// Rotation angle (radians) and translation distance between two poses.
template <typename T>
T RotationErrorRad(const Pose<T>& a, const Pose<T>& b) {
  return AngularDistance(a.q, b.q);
}
template <typename T>
T TranslationError(const Pose<T>& a, const Pose<T>& b) {
  return (a.p - b.p).norm();
}

}  // namespace geometry
}  // namespace autocal
