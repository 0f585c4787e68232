#include "autocal/factors/imu_factor.h"

#include "autocal/geometry/manifolds.h"

namespace autocal {
namespace factors {

namespace {

using Matrix15x3 = Eigen::Matrix<double, 15, 3, Eigen::RowMajor>;  // Ceres' layout
using JacobianMap3 = Eigen::Map<Eigen::Matrix<double, 15, 3, Eigen::RowMajor>>;
using JacobianMap4 = Eigen::Map<Eigen::Matrix<double, 15, 4, Eigen::RowMajor>>;

// U * J for a J whose non-zero rows are [first, first + Rows): since U is lower
// triangular, rows above `first` of the product vanish too. Coefficient-based products:
// Eigen's blocked GEMM path (chosen above 20 in rows + cols + depth) costs more than the
// arithmetic at these sizes.
template <int First, int Rows>
Matrix15x3 Whiten(const sensors::Matrix15d& U, const Eigen::Matrix<double, Rows, 3>& j_rows) {
  Matrix15x3 out;
  out.topRows<First>().setZero();
  out.bottomRows<15 - First>() = U.block<15 - First, Rows>(First, First).lazyProduct(j_rows);
  return out;
}

void StoreQuaternionJacobian(const Matrix15x3& j_tangent, const double* q, double* jacobian) {
  JacobianMap4 out(jacobian);
  out = geometry::LiftTangentJacobian<15>(Eigen::Matrix<double, 15, 3>(j_tangent), q);
}

void StoreJacobian(const Matrix15x3& j, double* jacobian) {
  JacobianMap3 out(jacobian);
  out = j;
}

}  // namespace

ImuDeltaMeasurement::ImuDeltaMeasurement(const sensors::ImuPreintegration& pim)
    : dt_s(pim.dt_s()),
      delta_q(pim.delta_q()),
      delta_v(pim.delta_v()),
      delta_p(pim.delta_p()),
      d_R_d_bg(pim.d_R_d_bg()),
      d_v_d_bg(pim.d_v_d_bg()),
      d_v_d_ba(pim.d_v_d_ba()),
      d_p_d_bg(pim.d_p_d_bg()),
      d_p_d_ba(pim.d_p_d_ba()),
      b_g_lin(pim.b_g_lin()),
      b_a_lin(pim.b_a_lin()),
      g_W(pim.gravity_W()),
      sqrt_information(pim.SqrtInformation()) {}

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
  const Eigen::Vector3d dbg = bg_i - m_.b_g_lin;
  const Eigen::Vector3d dba = ba_i - m_.b_a_lin;
  const Eigen::Vector3d phi_bias = m_.d_R_d_bg * dbg;
  const Eigen::Quaterniond dq = m_.delta_q * geometry::Exp(phi_bias);
  const Eigen::Vector3d dv = m_.delta_v + m_.d_v_d_bg * dbg + m_.d_v_d_ba * dba;
  const Eigen::Vector3d dp = m_.delta_p + m_.d_p_d_bg * dbg + m_.d_p_d_ba * dba;

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
  residual = U.lazyProduct(r);

  if (jacobians == nullptr) return true;

  // Eq. F11, on the right tangents; each block lists only its non-zero rows.
  const Eigen::Vector3d& r_phi = r.segment<3>(0);
  const Eigen::Matrix3d jr_inv = geometry::RightJacobianInverse(r_phi);
  if (jacobians[0] != nullptr) {
    Eigen::Matrix<double, 9, 3> j;
    j.topRows<3>() = -jr_inv * q_ij.conjugate().toRotationMatrix();
    j.middleRows<3>(3) = geometry::Hat(v_rel);
    j.bottomRows<3>() = geometry::Hat(p_rel);
    StoreQuaternionJacobian(Whiten<0, 9>(U, j), parameters[0], jacobians[0]);
  }
  if (jacobians[3] != nullptr) {
    Eigen::Matrix<double, 12, 3> j;
    j.topRows<3>() = -jr_inv * e_q.conjugate().toRotationMatrix() *
                     geometry::RightJacobian(phi_bias) * m_.d_R_d_bg;
    j.middleRows<3>(3) = -m_.d_v_d_bg;
    j.middleRows<3>(6) = -m_.d_p_d_bg;
    j.bottomRows<3>() = -Eigen::Matrix3d::Identity();
    StoreJacobian(Whiten<0, 12>(U, j), jacobians[3]);
  }
  if (jacobians[4] != nullptr) {
    // Non-zero rows v, p (3..9) and b_a (12..15); b_a's rows of U only touch itself.
    Eigen::Matrix<double, 6, 3> j;
    j.topRows<3>() = -m_.d_v_d_ba;
    j.bottomRows<3>() = -m_.d_p_d_ba;
    Matrix15x3 w = Whiten<3, 6>(U, j);
    w.bottomRows<3>() -= U.block<3, 3>(12, 12);
    StoreJacobian(w, jacobians[4]);
  }
  if (jacobians[5] != nullptr) {
    StoreQuaternionJacobian(Whiten<0, 3>(U, jr_inv), parameters[5], jacobians[5]);
  }
  // p and v enter only through R_i^T (p_j - p_i - v_i dt) and R_i^T (v_j - v_i): the
  // whitened blocks of keyframe i are those of keyframe j negated and combined.
  if (jacobians[1] != nullptr || jacobians[2] != nullptr || jacobians[6] != nullptr ||
      jacobians[7] != nullptr) {
    const Matrix15x3 j_p_j = Whiten<6, 3>(U, Eigen::Matrix3d(Rt_i));
    const Matrix15x3 j_v_j = Whiten<3, 3>(U, Eigen::Matrix3d(Rt_i));
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
