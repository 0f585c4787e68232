#include "autocal/factors/imu_factor.h"

namespace autocal {
namespace factors {

namespace {

using Matrix15x3 = Eigen::Matrix<double, 15, 3>;
using JacobianMap3 = Eigen::Map<Eigen::Matrix<double, 15, 3, Eigen::RowMajor>>;
using JacobianMap4 = Eigen::Map<Eigen::Matrix<double, 15, 4, Eigen::RowMajor>>;

// U * J for a J whose non-zero rows are the 3-row segments First..Last (of the five
// [phi, v, p, b_g, b_a]), given as j_rows. U is lower triangular, so output segment r only
// sums U_rs J_s over s in [First, min(r, Last)], and the segments above First vanish: the
// block-triangular product takes about half the operations of the dense one.
// Coefficient-based products: Eigen's blocked GEMM path costs more than the arithmetic at
// these sizes.
template <int First, int Last>
Matrix15x3 Whiten(const sensors::Matrix15d& U,
                  const Eigen::Matrix<double, 3 * (Last - First + 1), 3>& j_rows) {
  Matrix15x3 out;
  out.topRows<3 * First>().setZero();
  for (int r = First; r < 5; ++r) {
    auto out_r = out.middleRows<3>(3 * r);
    out_r.noalias() = U.block<3, 3>(3 * r, 3 * First).lazyProduct(j_rows.template topRows<3>());
    const int last = r < Last ? r : Last;
    for (int s = First + 1; s <= last; ++s) {
      out_r.noalias() +=
          U.block<3, 3>(3 * r, 3 * s).lazyProduct(j_rows.template middleRows<3>(3 * (s - First)));
    }
  }
  return out;
}

// X Hat(a) for a 3x3 X: row i is (x_i x a)^T, a third fewer operations than the product.
template <typename Derived>
Eigen::Matrix3d TimesHat(const Eigen::MatrixBase<Derived>& X, const Eigen::Vector3d& a) {
  Eigen::Matrix3d out;
  out.col(0) = a.z() * X.col(1) - a.y() * X.col(2);
  out.col(1) = a.x() * X.col(2) - a.z() * X.col(0);
  out.col(2) = a.y() * X.col(0) - a.x() * X.col(1);
  return out;
}

// Whiten<0, 2> for the q_i block, whose v and p rows are Hat(v_rel) and Hat(p_rel).
Matrix15x3 WhitenRotationI(const sensors::Matrix15d& U, const Eigen::Matrix3d& j_phi,
                           const Eigen::Vector3d& v_rel, const Eigen::Vector3d& p_rel) {
  Matrix15x3 out;
  for (int r = 0; r < 5; ++r) {
    auto out_r = out.middleRows<3>(3 * r);
    out_r.noalias() = U.block<3, 3>(3 * r, 0).lazyProduct(j_phi);
    if (r >= 1) out_r += TimesHat(U.block<3, 3>(3 * r, 3), v_rel);
    if (r >= 2) out_r += TimesHat(U.block<3, 3>(3 * r, 6), p_rel);
  }
  return out;
}

// Lifts the tangent Jacobian J to the quaternion's ambient coordinates, written straight
// into Ceres' block: J MinusJacobian(q) = 2 [w J + rows (v x j_r)^T, -J v] with q = [v, w]
// (geometry::LiftTangentRow), as column operations.
void StoreQuaternionJacobian(const Matrix15x3& J, const double* q, double* jacobian) {
  const double x = q[0], y = q[1], z = q[2], w = q[3];
  JacobianMap4 out(jacobian);
  out.col(0) = 2.0 * (w * J.col(0) + y * J.col(2) - z * J.col(1));
  out.col(1) = 2.0 * (w * J.col(1) + z * J.col(0) - x * J.col(2));
  out.col(2) = 2.0 * (w * J.col(2) + x * J.col(1) - y * J.col(0));
  out.col(3) = -2.0 * (x * J.col(0) + y * J.col(1) + z * J.col(2));
}

template <typename Derived>
void StoreJacobian(const Eigen::MatrixBase<Derived>& j, double* jacobian) {
  JacobianMap3 out(jacobian);
  out = j;
}

// The residual's square-root information. Its delta rows are the truth minus the measurement,
// its bias rows the drift b_j - b_i; the preintegration's covariance C is that of the
// measurement's error and the drift (ImuPreintegration::Covariance), whose cross blocks are
// positive: a bias drifting up carries the measured deltas up with it. The residual's
// covariance is therefore S C S, S = diag(-I9, I6), with Cholesky factor S L S and square-root
// information S U S: U with its bias-delta block negated (docs/factors.md, Eq. F11).
sensors::Matrix15d ResidualSqrtInformation(const sensors::ImuPreintegration& pim) {
  sensors::Matrix15d U = pim.SqrtInformation();
  U.bottomLeftCorner<6, 9>() *= -1.0;
  return U;
}

}  // namespace

ImuDeltaMeasurement::ImuDeltaMeasurement(const sensors::ImuPreintegration& pim)
    : dt_s(pim.dt_s()),
      deltas(pim.Linearized()),
      g_W(pim.gravity_W()),
      sqrt_information(ResidualSqrtInformation(pim)) {}

bool ImuFactor::Evaluate(double const* const* parameters, double* residuals,
                         double** jacobians) const {
  const Eigen::Map<const Eigen::Quaterniond> q_i(parameters[0]);
  const Eigen::Map<const Eigen::Vector3d> p_i(parameters[1]);
  const Eigen::Map<const Eigen::Vector3d> v_i(parameters[2]);
  const Eigen::Map<const Eigen::Vector3d> bg_i(parameters[3]);
  const Eigen::Map<const Eigen::Vector3d> ba_i(parameters[4]);
  const Eigen::Map<const Eigen::Quaterniond> q_j(parameters[5]);
  const Eigen::Map<const Eigen::Vector3d> p_j(parameters[6]);
  const Eigen::Map<const Eigen::Vector3d> v_j(parameters[7]);
  const Eigen::Map<const Eigen::Vector3d> bg_j(parameters[8]);
  const Eigen::Map<const Eigen::Vector3d> ba_j(parameters[9]);

  // Eq. F7: bias-corrected deltas.
  Eigen::Quaterniond dq;
  Eigen::Vector3d dv, dp, phi_bias;
  m_.deltas.Corrected<double>(bg_i, ba_i, &dq, &dv, &dp, &phi_bias);

  // Eq. F10.
  const double dt = m_.dt_s;
  const Eigen::Matrix3d Rt_i = q_i.conjugate().toRotationMatrix();
  const Eigen::Quaterniond q_ij = q_i.conjugate() * q_j;
  const Eigen::Quaterniond e_q = dq.conjugate() * q_ij;
  const Eigen::Vector3d v_rel = Rt_i * (v_j - v_i - m_.g_W * dt);
  const Eigen::Vector3d p_rel = Rt_i * (p_j - p_i - v_i * dt - 0.5 * dt * dt * m_.g_W);
  Eigen::Matrix<double, 15, 1> r;
  r.segment<3>(0) = geometry::Log(e_q);
  r.segment<3>(3) = v_rel - dv;
  r.segment<3>(6) = p_rel - dp;
  r.segment<3>(9) = bg_j - bg_i;
  r.segment<3>(12) = ba_j - ba_i;
  const sensors::Matrix15d& U = m_.sqrt_information;
  Eigen::Map<Eigen::Matrix<double, 15, 1>> residual(residuals);
  // Lower-triangular U: segment k of U r sums U_ks r_s over s <= k only.
  for (int k = 0; k < 5; ++k) {
    Eigen::Vector3d acc = U.block<3, 3>(3 * k, 0) * r.head<3>();
    for (int s = 1; s <= k; ++s) acc.noalias() += U.block<3, 3>(3 * k, 3 * s) * r.segment<3>(3 * s);
    residual.segment<3>(3 * k) = acc;
  }

  if (jacobians == nullptr) return true;

  // Eq. F11, on the right tangents; each block lists only its non-zero rows.
  const Eigen::Vector3d& r_phi = r.segment<3>(0);
  const Eigen::Matrix3d jr_inv = geometry::RightJacobianInverse(r_phi);
  if (jacobians[0] != nullptr) {
    // Rows phi: -Jr^-1 R_ij^T, v: Hat(v_rel), p: Hat(p_rel).
    const Eigen::Matrix3d j_phi = -jr_inv * q_ij.conjugate().toRotationMatrix();
    StoreQuaternionJacobian(WhitenRotationI(U, j_phi, v_rel, p_rel), parameters[0], jacobians[0]);
  }
  if (jacobians[3] != nullptr) {
    // Rows phi, v, p, and -I on b_g, whose column of U only reaches b_g and b_a.
    Eigen::Matrix<double, 9, 3> j;
    j.topRows<3>() = -jr_inv * e_q.conjugate().toRotationMatrix() *
                     geometry::RightJacobian(phi_bias) * m_.deltas.d_R_d_bg;
    j.middleRows<3>(3) = -m_.deltas.d_v_d_bg;
    j.bottomRows<3>() = -m_.deltas.d_p_d_bg;
    Matrix15x3 w = Whiten<0, 2>(U, j);
    w.bottomRows<6>() -= U.block<6, 3>(9, 9);
    StoreJacobian(w, jacobians[3]);
  }
  if (jacobians[4] != nullptr) {
    // Non-zero rows v, p (3..9) and b_a (12..15); b_a's rows of U only touch itself.
    Eigen::Matrix<double, 6, 3> j;
    j.topRows<3>() = -m_.deltas.d_v_d_ba;
    j.bottomRows<3>() = -m_.deltas.d_p_d_ba;
    Matrix15x3 w = Whiten<1, 2>(U, j);
    w.bottomRows<3>() -= U.block<3, 3>(12, 12);
    StoreJacobian(w, jacobians[4]);
  }
  if (jacobians[5] != nullptr) {
    StoreQuaternionJacobian(Whiten<0, 0>(U, jr_inv), parameters[5], jacobians[5]);
  }
  // p and v enter only through R_i^T (p_j - p_i - v_i dt) and R_i^T (v_j - v_i): the
  // whitened blocks of keyframe i are those of keyframe j negated and combined.
  if (jacobians[1] != nullptr || jacobians[2] != nullptr || jacobians[6] != nullptr ||
      jacobians[7] != nullptr) {
    const Matrix15x3 j_p_j = Whiten<2, 2>(U, Rt_i);
    const Matrix15x3 j_v_j = Whiten<1, 1>(U, Rt_i);
    if (jacobians[1] != nullptr) StoreJacobian(-j_p_j, jacobians[1]);
    if (jacobians[2] != nullptr) StoreJacobian(-j_v_j - dt * j_p_j, jacobians[2]);
    if (jacobians[6] != nullptr) StoreJacobian(j_p_j, jacobians[6]);
    if (jacobians[7] != nullptr) StoreJacobian(j_v_j, jacobians[7]);
  }
  if (jacobians[8] != nullptr) StoreJacobian(U.middleCols<3>(9), jacobians[8]);
  if (jacobians[9] != nullptr) StoreJacobian(U.middleCols<3>(12), jacobians[9]);
  return true;
}

}  // namespace factors
}  // namespace autocal
