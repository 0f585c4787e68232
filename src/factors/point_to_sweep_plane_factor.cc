#include "autocal/factors/point_to_sweep_plane_factor.h"

#include "autocal/geometry/so3.h"
#include "factors/sigma_check.h"

namespace autocal {
namespace factors {

namespace {

// The ambient row of a tangent row a at q: a^T lift = LiftTangentRow(a, q), i.e.
// 2 (w a + v x a) for the vector part and -2 v . a for the scalar part.
Eigen::Matrix<double, 3, 4> Lift(const double* q_xyzw) {
  Eigen::Matrix<double, 3, 4> lift;
  const Eigen::Map<const Eigen::Vector3d> v(q_xyzw);
  lift.leftCols<3>() = 2.0 * (q_xyzw[3] * Eigen::Matrix3d::Identity() - geometry::Hat(v));
  lift.col(3) = -2.0 * v;
  return lift;
}

// A Jacobian row of N entries in Ceres' row-major storage.
template <int N>
Eigen::Map<Eigen::Matrix<double, 1, N>> Row(double* jacobian) {
  return Eigen::Map<Eigen::Matrix<double, 1, N>>(jacobian);
}

}  // namespace

PointToSweepPlaneFactor::Frame::Frame(double const* const* parameters)
    : R_k(Eigen::Map<const Eigen::Quaterniond>(parameters[0]).toRotationMatrix()),
      p_k(parameters[1]),
      v_k(parameters[2]),
      R_j(Eigen::Map<const Eigen::Quaterniond>(parameters[3]).toRotationMatrix()),
      p_j(parameters[4]),
      v_j(parameters[5]),
      R_I_L(Eigen::Map<const Eigen::Quaterniond>(parameters[6]).toRotationMatrix()),
      p_I_L(parameters[7]),
      time_offset_s(parameters[8][0]),
      lift_k(Lift(parameters[0])),
      lift_j(Lift(parameters[3])),
      lift_I_L_left(R_I_L * Lift(parameters[6])) {}

PointToSweepPlaneFactor::Side::Side(const PointMotion& motion, const Eigen::Vector3d& g_W)
    : delta_R(motion.delta_q.toRotationMatrix()),
      omega_rad_s(motion.omega_rad_s),
      delta_v(motion.delta_v),
      delta_p(motion.delta_p),
      gravity_velocity(g_W * motion.dt_s),
      gravity_position(0.5 * g_W * motion.dt_s * motion.dt_s),
      dt_s(motion.dt_s) {}

PointToSweepPlaneFactor::Terms::Terms(const PointToSweepPlaneMeasurement& measurement,
                                      const Eigen::Vector3d& g_W, uint32_t plane_side)
    : point_(measurement.motion, g_W),
      p_L_(measurement.p_L),
      n_L_(measurement.plane_L.normal),
      d_L_(measurement.plane_L.d),
      inv_sigma_(1.0 / measurement.sigma_m),
      offset_linearization_s_(measurement.offset_linearization_s),
      plane_side_(plane_side) {
  internal::CheckSigma(measurement.sigma_m, "point-to-sweep-plane factor: sigma_m");
}

PointToSweepPlaneFactor::PlaneFrame::PlaneFrame(const Frame& f, const Side& plane)
    : M_j(f.R_j * plane.delta_R),
      delta_R(plane.delta_R),
      omega_rad_s(plane.omega_rad_s),
      c0(f.p_j + plane.dt_s * f.v_j + plane.gravity_position),
      c1(f.v_j + plane.gravity_velocity),
      b0(f.p_I_L + plane.delta_R.transpose() * plane.delta_p),
      b1(plane.omega_rad_s.cross(f.p_I_L) + plane.delta_R.transpose() * plane.delta_v),
      dt_s(plane.dt_s) {}

bool PointToSweepPlaneFactor::Evaluate(double const* const* parameters, double* residuals,
                                       double** jacobians) const {
  const Frame frame(parameters);
  terms_.Evaluate(frame, PlaneFrame(frame, plane_), residuals, jacobians);
  return true;
}

double PointToSweepPlaneFactor::Terms::Core(const Frame& f, const PlaneFrame& plane, Rows* rows,
                                            bool calibration_rows) const {
  const double delta = f.time_offset_s - offset_linearization_s_;

  // Point side (Eq. P1-P3) with dR (I + delta Hat(omega)) applied as dR (x + delta omega x x):
  //   lever = dR (x_I + delta omega_k x x_I) + dp + delta dv,
  //   p_W = R_k lever + p_k + (dt + delta) v_k + g dt^2/2 + delta g dt.
  const Eigen::Vector3d rotated_p = f.R_I_L * p_L_;  // x_I - p_I_L
  const Eigen::Vector3d x_I = rotated_p + f.p_I_L;
  const Eigen::Vector3d spun_x = point_.omega_rad_s.cross(x_I);  // Hat(omega_k) x_I
  const Eigen::Vector3d lever =
      point_.delta_R * (x_I + delta * spun_x) + point_.delta_p + delta * point_.delta_v;
  const Eigen::Vector3d p_W = f.R_k * lever + f.p_k + (point_.dt_s + delta) * f.v_k +
                              point_.gravity_position + delta * point_.gravity_velocity;

  // Plane side, with B = dR_j (I + delta Hat(omega_j)):
  //   a = B R_I_L n_L (the normal in I_j),  b = B p_I_L + dp_j + delta dv_j,
  //   w = p_W - p_j - (dt_j + delta) v_j - g dt_j^2/2 - delta g dt_j,   z = R_j^T w,
  //   r sigma = a . (z - b) + d_L.                                                 (Eq. P7)
  // With alpha = dR_j^T a = n_I + delta omega_j x n_I and t = dR_j^T (z - b) = M_j^T w - b'
  // (PlaneFrame), a . (z - b) = alpha . t: neither a nor z is formed.
  const Eigen::Vector3d n_I = f.R_I_L * n_L_;
  const Eigen::Vector3d spun_n = plane.omega_rad_s.cross(n_I);
  const Eigen::Vector3d alpha = n_I + delta * spun_n;
  const Eigen::Vector3d w = p_W - (plane.c0 + delta * plane.c1);
  const Eigen::Vector3d b_rotated = plane.b0 + delta * plane.b1;  // b' = dR_j^T b
  const Eigen::Vector3d t = plane.M_j.transpose() * w - b_rotated;
  const double residual = (alpha.dot(t) + d_L_) * inv_sigma_;
  if (rows == nullptr) return residual;

  // The point side enters through n_W . p_W with n_W = R_j a = M_j alpha: the Jacobians of
  // Eq. (P5) with that normal; m = R_k^T n_W / sigma and m_x = (I + delta Hat(omega_k))^T
  // dR^T m, the gradient in x_I.
  const Eigen::Vector3d n_W = plane.M_j * alpha * inv_sigma_;
  const Eigen::Vector3d m = f.R_k.transpose() * n_W;
  const Eigen::Vector3d u = point_.delta_R.transpose() * m;
  const Eigen::Vector3d m_x = u + delta * u.cross(point_.omega_rad_s);
  rows->theta_k = lever.cross(m);
  rows->p_k = n_W;
  rows->v_k = (point_.dt_s + delta) * n_W;
  // Plane side: d/dtheta_j of a . R_j^T w is (a x z)^T (Eq. P8), and with z = dR_j (t + b'),
  // a x z = dR_j (alpha x (t + b')).
  rows->theta_j = inv_sigma_ * (plane.delta_R * alpha.cross(t + b_rotated));
  rows->v_j = -(plane.dt_s + delta) * n_W;
  if (!calibration_rows) return residual;
  // B^T (z - b) = (I - delta Hat(omega_j)) t = t + delta t x omega_j.
  // Point side through x_I: p_L x R_I_L^T m_x. Plane side through a = B R_I_L n_L:
  // n_L x R_I_L^T B^T (z - b). With p_L x R^T y = R^T (R p_L x y), both are R_I_L^T times the
  // left tangent's row below.
  const Eigen::Vector3d e = t + delta * t.cross(plane.omega_rad_s);
  rows->phi_I_L = rotated_p.cross(m_x) + inv_sigma_ * n_I.cross(e);
  // B^T a = alpha + delta alpha x omega_j.
  const Eigen::Vector3d B_t_a = alpha + delta * alpha.cross(plane.omega_rad_s);
  rows->p_I_L = m_x - inv_sigma_ * B_t_a;
  // Point side: Eq. (P5) with n_W, m . dR Hat(omega) x_I = u . spun_x. Plane side:
  // da/d(delta) = dR_j spun_n, db/d(delta) = dR_j (omega_j x p_I_L) + dv_j,
  // dz/d(delta) = -R_j^T (v_j + g dt_j); R_j a = sigma n_W; so the plane side's is
  // (spun_n . t - alpha . b1) / sigma - n_W . c1.
  const double offset_point =
      u.dot(spun_x) + m.dot(point_.delta_v) + n_W.dot(f.v_k + point_.gravity_velocity);
  const double offset_plane =
      inv_sigma_ * (spun_n.dot(t) - alpha.dot(plane.b1)) - n_W.dot(plane.c1);
  rows->offset = offset_point + offset_plane;
  return residual;
}

void PointToSweepPlaneFactor::Terms::Evaluate(const Frame& f, const PlaneFrame& plane,
                                              double* residual, double** jacobians) const {
  if (jacobians == nullptr) {
    residual[0] = Core(f, plane, nullptr, false);
    return;
  }
  // The calibration's rows only when asked for (a batch solve with the calibration held fixed
  // asks for none of them).
  const bool calibration_rows =
      jacobians[6] != nullptr || jacobians[7] != nullptr || jacobians[8] != nullptr;
  Rows rows;
  residual[0] = Core(f, plane, &rows, calibration_rows);
  if (jacobians[0] != nullptr) Row<4>(jacobians[0]) = rows.theta_k.transpose() * f.lift_k;
  if (jacobians[1] != nullptr) Row<3>(jacobians[1]) = rows.p_k.transpose();
  if (jacobians[2] != nullptr) Row<3>(jacobians[2]) = rows.v_k.transpose();
  if (jacobians[3] != nullptr) Row<4>(jacobians[3]) = rows.theta_j.transpose() * f.lift_j;
  if (jacobians[4] != nullptr) Row<3>(jacobians[4]) = -rows.p_k.transpose();
  if (jacobians[5] != nullptr) Row<3>(jacobians[5]) = rows.v_j.transpose();
  if (jacobians[6] != nullptr) {
    Row<4>(jacobians[6]) = rows.phi_I_L.transpose() * f.lift_I_L_left;
  }
  if (jacobians[7] != nullptr) Row<3>(jacobians[7]) = rows.p_I_L.transpose();
  if (jacobians[8] != nullptr) jacobians[8][0] = rows.offset;
}

void PointToSweepPlaneFactor::Terms::EvaluateTangent(const Frame& f, const PlaneFrame& plane,
                                                     double* residual, double* row,
                                                     size_t stride) const {
  Rows rows;
  residual[0] = Core(f, plane, &rows, true);
  const Eigen::Vector3d theta_I_L = f.R_I_L.transpose() * rows.phi_I_L;
  const Eigen::Vector3d* blocks[] = {&rows.theta_k, &rows.p_k,  &rows.v_k,  &rows.theta_j,
                                     &rows.v_j,     &theta_I_L, &rows.p_I_L};
  double* out = row;
  for (const Eigen::Vector3d* block : blocks) {
    for (int c = 0; c < 3; ++c, out += stride) *out = (*block)(c);
  }
  *out = rows.offset;
}

ceres::CostFunction* CreatePointToSweepPlaneAutoDiff(
    const PointToSweepPlaneMeasurement& measurement, const Eigen::Vector3d& g_W) {
  return new ceres::AutoDiffCostFunction<PointToSweepPlaneResidual, 1, 4, 3, 3, 4, 3, 3, 4, 3, 1>(
      new PointToSweepPlaneResidual(measurement, g_W));
}

}  // namespace factors
}  // namespace autocal
