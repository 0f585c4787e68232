#pragma once

// Ceres 2.1 manifolds for autocal's parameter blocks (Manifold API only).
//
// Orientation blocks (q_W_I, q_I_L, q_I_V) are unit quaternions stored in Eigen's order
// [x, y, z, w] and perturbed on the right, in the body frame:
//   Plus(q, delta) = q * Exp(delta),   Minus(y, x) = Log(x^-1 * y).
// This matches the right-perturbation Jacobians of the factors (Forster et al. 2017).
// An analytic cost function that knows its Jacobian J_tangent with respect to delta
// reports the ambient (4-column) Jacobian as J_tangent * MinusJacobian(q)
// (see LiftTangentJacobian), which the manifold maps back exactly since
// MinusJacobian(q) * PlusJacobian(q) = I.

#include <ceres/manifold.h>
#include <ceres/product_manifold.h>

#include <Eigen/Core>

namespace autocal {
namespace geometry {

class RightQuaternionManifold final : public ceres::Manifold {
 public:
  int AmbientSize() const override { return 4; }
  int TangentSize() const override { return 3; }
  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override;
  bool PlusJacobian(const double* x, double* jacobian) const override;
  bool Minus(const double* y, const double* x, double* y_minus_x) const override;
  bool MinusJacobian(const double* x, double* jacobian) const override;
};

// Pose as one 7-vector [qx, qy, qz, qw, px, py, pz]: right-perturbed rotation and a
// Euclidean translation (tangent [dphi, dp]).
using PoseManifold = ceres::ProductManifold<RightQuaternionManifold, ceres::EuclideanManifold<3>>;

// 3x4 row-major Jacobian d(delta)/d(q) at delta = 0 for the right-perturbed quaternion.
Eigen::Matrix<double, 3, 4, Eigen::RowMajor> QuaternionMinusJacobian(const double* q_xyzw);

// Maps a Jacobian with respect to the right tangent (N x 3) to the ambient quaternion
// coordinates (N x 4) expected by Ceres for a block with RightQuaternionManifold.
template <int N>
Eigen::Matrix<double, N, 4, Eigen::RowMajor> LiftTangentJacobian(
    const Eigen::Matrix<double, N, 3>& j_tangent, const double* q_xyzw) {
  return j_tangent * QuaternionMinusJacobian(q_xyzw);
}

// The same for a single row, written out for hot factors:
// a * MinusJacobian(q) = 2 [w a + (v x a)^T, -a . v] with q = [v, w].
inline void LiftTangentRow(const Eigen::RowVector3d& a, const double* q_xyzw, double* ambient) {
  const Eigen::Map<const Eigen::Vector3d> v(q_xyzw);
  const double w = q_xyzw[3];
  const Eigen::Vector3d head = 2.0 * (w * a.transpose() + v.cross(a.transpose()));
  ambient[0] = head.x();
  ambient[1] = head.y();
  ambient[2] = head.z();
  ambient[3] = -2.0 * a.dot(v.transpose());
}

// The same for a right-tangent row given rotated, a = (R(q)^T b)^T, without the rotation:
// R(q)^T b is b in the left tangent (q Exp(R^T b) = Exp(b) q), and
// a * MinusJacobian(q) = 2 [w b - v x b, -b . v].
inline void LiftRotatedTangentRow(const Eigen::Vector3d& b, const double* q_xyzw, double* ambient) {
  const Eigen::Map<const Eigen::Vector3d> v(q_xyzw);
  const double w = q_xyzw[3];
  const Eigen::Vector3d head = 2.0 * (w * b - v.cross(b));
  ambient[0] = head.x();
  ambient[1] = head.y();
  ambient[2] = head.z();
  ambient[3] = -2.0 * b.dot(v);
}

}  // namespace geometry
}  // namespace autocal
