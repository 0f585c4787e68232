#include "autocal/factors/point_to_plane_factor.h"

#include "autocal/geometry/manifolds.h"
#include "factors/sigma_check.h"

namespace autocal {
namespace factors {

PointToPlaneFactor::PointToPlaneFactor(const PointToPlaneMeasurement& measurement,
                                       const Eigen::Vector3d& g_W)
    : delta_R_(measurement.motion.delta_q.toRotationMatrix()),
      delta_R_omega_hat_(delta_R_ * geometry::Hat(measurement.motion.omega_rad_s)),
      p_L_(measurement.p_L),
      n_W_over_sigma_(measurement.plane.normal / measurement.sigma_m),
      delta_v_(measurement.motion.delta_v),
      delta_p_(measurement.motion.delta_p),
      n_gravity_velocity_(n_W_over_sigma_.dot(g_W) * measurement.motion.dt_s),
      n_gravity_position_(0.5 * n_W_over_sigma_.dot(g_W) * measurement.motion.dt_s *
                          measurement.motion.dt_s),
      d_over_sigma_(measurement.plane.d / measurement.sigma_m),
      dt_s_(measurement.motion.dt_s),
      offset_linearization_s_(measurement.offset_linearization_s) {
  internal::CheckSigma(measurement.sigma_m, "point-to-plane factor: sigma_m");
}

bool PointToPlaneFactor::Evaluate(double const* const* parameters, double* residuals,
                                  double** jacobians) const {
  const Eigen::Map<const Eigen::Quaterniond> q_W_I(parameters[0]);
  const Eigen::Map<const Eigen::Vector3d> p_W_I(parameters[1]);
  const Eigen::Map<const Eigen::Vector3d> v_W_I(parameters[2]);
  const Eigen::Map<const Eigen::Quaterniond> q_I_L(parameters[3]);
  const Eigen::Map<const Eigen::Vector3d> p_I_L(parameters[4]);
  const double delta = parameters[5][0] - offset_linearization_s_;

  // Eq. (P1-P4) with the normal taken into the keyframe's body frame, m = R_k^T n / sigma,
  // so that the residual is m . (R_k^T-part) + n . (world part):
  //   r = m . (dR x_I + delta dR Hat(omega) x_I + dp + delta dv)
  //     + n . (p_k + (dt + delta) v_k + 1/2 g dt^2 + delta g dt) / sigma + d / sigma.
  const Eigen::Vector3d m = q_W_I.conjugate() * n_W_over_sigma_;
  const Eigen::Vector3d x_I = q_I_L * p_L_ + p_I_L;  // the point in I(t)
  // The motion to the point's instant at this offset: dR + delta dR Hat(omega).
  const Eigen::Matrix3d motion = delta_R_ + delta * delta_R_omega_hat_;
  const Eigen::Vector3d lever = motion * x_I + delta_p_ + delta * delta_v_;
  // n . v_k / sigma enters the residual and the offset Jacobian.
  const double n_v = n_W_over_sigma_.dot(v_W_I);
  residuals[0] = m.dot(lever) + n_W_over_sigma_.dot(p_W_I) + (dt_s_ + delta) * n_v +
                 n_gravity_position_ + delta * n_gravity_velocity_ + d_over_sigma_;
  if (jacobians == nullptr) return true;

  if (jacobians[0] != nullptr) {
    // d/dtheta_k of n^T R_k Exp(theta) lever = -n^T R_k Hat(lever) = (lever x m)^T.
    geometry::LiftTangentRow(lever.cross(m).transpose(), parameters[0], jacobians[0]);
  }
  if (jacobians[1] != nullptr) {
    Eigen::Map<Eigen::RowVector3d> j(jacobians[1]);
    j = n_W_over_sigma_.transpose();
  }
  if (jacobians[2] != nullptr) {
    Eigen::Map<Eigen::RowVector3d> j(jacobians[2]);
    j = (dt_s_ + delta) * n_W_over_sigma_.transpose();
  }
  if (jacobians[3] != nullptr || jacobians[4] != nullptr) {
    // d r / d x_I = m^T (dR + delta dR Hat(omega)).
    const Eigen::Vector3d m_x = motion.transpose() * m;
    if (jacobians[3] != nullptr) {
      // d x_I / d theta_IL = -R_I_L Hat(p_L), so the tangent row is p_L x R_I_L^T m_x
      // = R_I_L^T (R_I_L p_L x m_x), with R_I_L p_L = x_I - p_I_L.
      geometry::LiftRotatedTangentRow((x_I - p_I_L).cross(m_x), parameters[3], jacobians[3]);
    }
    if (jacobians[4] != nullptr) {
      Eigen::Map<Eigen::RowVector3d> j(jacobians[4]);
      j = m_x.transpose();
    }
  }
  if (jacobians[5] != nullptr) {
    jacobians[5][0] = m.dot(delta_R_omega_hat_ * x_I + delta_v_) + n_v + n_gravity_velocity_;
  }
  return true;
}

ceres::CostFunction* CreatePointToPlaneAutoDiff(const PointToPlaneMeasurement& measurement,
                                                const Eigen::Vector3d& g_W) {
  return new ceres::AutoDiffCostFunction<PointToPlaneResidual, 1, 4, 3, 3, 4, 3, 1>(
      new PointToPlaneResidual(measurement, g_W));
}

Eigen::Vector3d PointInWorld(const PropagatedPose<double>& pose, const Eigen::Quaterniond& q_I_L,
                             const Eigen::Vector3d& p_I_L, const Eigen::Vector3d& p_L) {
  return pose.R_W_I * (q_I_L * p_L + p_I_L) + pose.p_W_I;
}

}  // namespace factors
}  // namespace autocal
