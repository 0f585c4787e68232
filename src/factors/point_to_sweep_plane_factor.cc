#include "autocal/factors/point_to_sweep_plane_factor.h"

#include "autocal/geometry/manifolds.h"

namespace autocal {
namespace factors {

PointToSweepPlaneFactor::Side::Side(const PointMotion& motion, const Eigen::Vector3d& g_W)
    : delta_R(motion.delta_q.toRotationMatrix()),
      delta_R_omega_hat(delta_R * geometry::Hat(motion.omega_rad_s)),
      delta_v(motion.delta_v),
      delta_p(motion.delta_p),
      gravity_velocity(g_W * motion.dt_s),
      gravity_position(0.5 * g_W * motion.dt_s * motion.dt_s),
      dt_s(motion.dt_s) {}

PointToSweepPlaneFactor::PointToSweepPlaneFactor(const PointToSweepPlaneMeasurement& measurement,
                                                 const Eigen::Vector3d& g_W)
    : point_(measurement.motion, g_W),
      plane_(measurement.plane_motion, g_W),
      p_L_(measurement.p_L),
      n_L_(measurement.plane_L.normal),
      d_L_(measurement.plane_L.d),
      inv_sigma_(1.0 / measurement.sigma_m),
      offset_linearization_s_(measurement.offset_linearization_s) {}

bool PointToSweepPlaneFactor::Evaluate(double const* const* parameters, double* residuals,
                                       double** jacobians) const {
  const Eigen::Map<const Eigen::Quaterniond> q_k(parameters[0]);
  const Eigen::Map<const Eigen::Vector3d> p_k(parameters[1]);
  const Eigen::Map<const Eigen::Vector3d> v_k(parameters[2]);
  const Eigen::Map<const Eigen::Quaterniond> q_j(parameters[3]);
  const Eigen::Map<const Eigen::Vector3d> p_j(parameters[4]);
  const Eigen::Map<const Eigen::Vector3d> v_j(parameters[5]);
  const Eigen::Map<const Eigen::Quaterniond> q_I_L(parameters[6]);
  const Eigen::Map<const Eigen::Vector3d> p_I_L(parameters[7]);
  const double delta = parameters[8][0] - offset_linearization_s_;

  // Point side (Eq. P1-P3): p_W = R_k lever + p_k + (dt + delta) v_k + g dt^2/2 + delta g dt.
  const Eigen::Matrix3d R_I_L = q_I_L.toRotationMatrix();
  const Eigen::Vector3d x_I = R_I_L * p_L_ + p_I_L;
  const Eigen::Vector3d spun_x = point_.delta_R_omega_hat * x_I;
  const Eigen::Vector3d lever =
      point_.delta_R * x_I + delta * spun_x + point_.delta_p + delta * point_.delta_v;
  const Eigen::Vector3d p_W = q_k * lever + p_k + (point_.dt_s + delta) * v_k +
                              point_.gravity_position + delta * point_.gravity_velocity;

  // Plane side, with B = dR_j (I + delta Hat(omega_j)):
  //   a = B R_I_L n_L (the normal in I_j),  b = B p_I_L + dp_j + delta dv_j,
  //   w = p_W - p_j - (dt_j + delta) v_j - g dt_j^2/2 - delta g dt_j,   z = R_j^T w,
  //   r sigma = a . (z - b) + d_L.                                                 (Eq. P7)
  const Eigen::Vector3d n_I_L = R_I_L * n_L_;
  const Eigen::Vector3d a = plane_.delta_R * n_I_L +
                            delta * (plane_.delta_R_omega_hat * n_I_L);
  const Eigen::Vector3d b = plane_.delta_R * p_I_L + delta * (plane_.delta_R_omega_hat * p_I_L) +
                            plane_.delta_p + delta * plane_.delta_v;
  const Eigen::Vector3d w = p_W - p_j - (plane_.dt_s + delta) * v_j - plane_.gravity_position -
                            delta * plane_.gravity_velocity;
  const Eigen::Vector3d z = q_j.conjugate() * w;
  const Eigen::Vector3d z_minus_b = z - b;
  residuals[0] = (a.dot(z_minus_b) + d_L_) * inv_sigma_;
  if (jacobians == nullptr) return true;

  // The point side enters through n_W . p_W with n_W = R_j a: the Jacobians of Eq. (P5)
  // with that normal; m = R_k^T n_W / sigma.
  const Eigen::Vector3d n_W = q_j * a * inv_sigma_;
  const Eigen::Vector3d m = q_k.conjugate() * n_W;
  const Eigen::Vector3d m_x =
      point_.delta_R.transpose() * m + delta * (point_.delta_R_omega_hat.transpose() * m);
  if (jacobians[0] != nullptr) {
    geometry::LiftTangentRow(lever.cross(m).transpose(), parameters[0], jacobians[0]);
  }
  if (jacobians[1] != nullptr) {
    Eigen::Map<Eigen::RowVector3d> j1(jacobians[1]);
    j1 = n_W.transpose();
  }
  if (jacobians[2] != nullptr) {
    Eigen::Map<Eigen::RowVector3d> j2(jacobians[2]);
    j2 = (point_.dt_s + delta) * n_W.transpose();
  }
  // Plane side: d/dtheta_j of a . R_j^T w is (a x z)^T (Eq. P8).
  if (jacobians[3] != nullptr) {
    geometry::LiftTangentRow(a.cross(z).transpose() * inv_sigma_, parameters[3], jacobians[3]);
  }
  if (jacobians[4] != nullptr) {
    Eigen::Map<Eigen::RowVector3d> j4(jacobians[4]);
    j4 = -n_W.transpose();
  }
  if (jacobians[5] != nullptr) {
    Eigen::Map<Eigen::RowVector3d> j5(jacobians[5]);
    j5 = -(plane_.dt_s + delta) * n_W.transpose();
  }
  const Eigen::Matrix3d B = plane_.delta_R + delta * plane_.delta_R_omega_hat;
  if (jacobians[6] != nullptr) {
    // Point side through x_I; plane side through a = B R_I_L n_L:
    // d(a . (z - b))/dphi = (n_L x e)^T with e = R_I_L^T B^T (z - b).
    const Eigen::Vector3d e = R_I_L.transpose() * (B.transpose() * z_minus_b);
    const Eigen::Vector3d gradient =
        p_L_.cross(R_I_L.transpose() * m_x) + n_L_.cross(e) * inv_sigma_;
    geometry::LiftTangentRow(gradient.transpose(), parameters[6], jacobians[6]);
  }
  if (jacobians[7] != nullptr) {
    Eigen::Map<Eigen::RowVector3d> j7(jacobians[7]);
    j7 =
        m_x.transpose() - (B.transpose() * a).transpose() * inv_sigma_;
  }
  if (jacobians[8] != nullptr) {
    // Point side: Eq. (P5) with n_W. Plane side: da/d(delta) = dR_j Hat(omega_j) R_I_L n_L,
    // db/d(delta) = dR_j Hat(omega_j) p_I_L + dv_j, dz/d(delta) = -R_j^T (v_j + g dt_j).
    const double point_side =
        m.dot(spun_x + point_.delta_v) + n_W.dot(v_k + point_.gravity_velocity);
    const Eigen::Vector3d a_dot = plane_.delta_R_omega_hat * n_I_L;
    const Eigen::Vector3d b_dot = plane_.delta_R_omega_hat * p_I_L + plane_.delta_v;
    const double plane_side = a_dot.dot(z_minus_b) -
                              (q_j * a).dot(v_j + plane_.gravity_velocity) - a.dot(b_dot);
    jacobians[8][0] = point_side + plane_side * inv_sigma_;
  }
  return true;
}

ceres::CostFunction* CreatePointToSweepPlaneAutoDiff(
    const PointToSweepPlaneMeasurement& measurement, const Eigen::Vector3d& g_W) {
  return new ceres::AutoDiffCostFunction<PointToSweepPlaneResidual, 1, 4, 3, 3, 4, 3, 3, 4, 3, 1>(
      new PointToSweepPlaneResidual(measurement, g_W));
}

}  // namespace factors
}  // namespace autocal
