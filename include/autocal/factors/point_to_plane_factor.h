#pragma once

// LiDAR point-to-plane factor with extrinsic and time offset (docs/estimation.md, section
// "LiDAR point-to-plane factor").
//
// A point p_L stamped t_sweep + tau by the LiDAR was measured at IMU time
// t = t_sweep + tau + offset. The IMU pose at t is its keyframe state propagated with the
// IMU: with dt the point's time after the keyframe (negative before it) at the linearization
// offset offset_0 and delta = offset - offset_0 (Eq. P1-P3),
//   R(t) = R_k * dR * (I + delta * Hat(omega))
//   v(t) = v_k + g_W dt + R_k dv
//   p(t) = p_k + v_k dt + 1/2 g_W dt^2 + R_k dp + delta * v(t)
// where (dR, dv, dp) are the preintegrated IMU deltas from t_k to t_k + dt and omega the
// bias-corrected body rate's mean over one sweep's span centred on t (Eq. P1b). The point in W is
// p_W = R(t) (R_I_L p_L + p_I_L) + p(t) and the residual its signed distance to the plane n_W . x +
// d = 0, whitened by sigma (Eq. P4). The model is first order in delta; estimators re-propagate
// (delta -> 0) between solves.
//
// Parameter blocks: q_W_I (4, RightQuaternionManifold), p_W_I (3), v_W_I (3),
// q_I_L (4, RightQuaternionManifold), p_I_L (3), time_offset_lidar_imu_s (1).

#include <ceres/ceres.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "autocal/geometry/plane.h"
#include "autocal/geometry/so3.h"

namespace autocal {
namespace factors {

// IMU motion from a keyframe to the instant a point was measured (at the linearization
// offset; before or after the keyframe), as IMU propagation predicts it.
struct PointMotion {
  double dt_s = 0.0;                                            // t - t_k
  Eigen::Quaterniond delta_q = Eigen::Quaterniond::Identity();  // R_Ik_I(t)
  Eigen::Vector3d delta_v = Eigen::Vector3d::Zero();            // preintegrated, in I_k
  Eigen::Vector3d delta_p = Eigen::Vector3d::Zero();            // preintegrated, in I_k
  Eigen::Vector3d omega_rad_s = Eigen::Vector3d::Zero();        // mean body rate (Eq. P1b)
};

struct PointToPlaneMeasurement {
  Eigen::Vector3d p_L = Eigen::Vector3d::Zero();  // the point in the LiDAR frame
  PointMotion motion;
  geometry::Plane plane;                // in W: normal . x + d = 0
  double sigma_m = 0.02;                // 1-sigma of the point-to-plane distance
  double offset_linearization_s = 0.0;  // offset_0
};

// Analytic Jacobians; the hot path of every LiDAR calibration.
class PointToPlaneFactor final : public ceres::SizedCostFunction<1, 4, 3, 3, 4, 3, 1> {
 public:
  PointToPlaneFactor(const PointToPlaneMeasurement& measurement, const Eigen::Vector3d& g_W);

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

 private:
  Eigen::Matrix3d delta_R_;
  Eigen::Matrix3d delta_R_omega_hat_;  // dR * Hat(omega)
  Eigen::Vector3d p_L_;
  Eigen::Vector3d n_W_over_sigma_;
  Eigen::Vector3d delta_v_;
  Eigen::Vector3d delta_p_;
  double n_gravity_velocity_;  // n . g_W dt / sigma
  double n_gravity_position_;  // n . g_W dt^2 / (2 sigma)
  double d_over_sigma_;
  double dt_s_;
  double offset_linearization_s_;
};

// The IMU pose at a point's instant (Eq. P1-P3) for any scalar: the keyframe state
// (q_W_I, p_W_I, v_W_I) propagated by `motion`, delta = offset - offset_0.
template <typename T>
struct PropagatedPose {
  Eigen::Matrix<T, 3, 3> R_W_I;
  Eigen::Matrix<T, 3, 1> p_W_I;
};

template <typename T>
PropagatedPose<T> PropagateKeyframe(const Eigen::Quaternion<T>& q_W_I,
                                    const Eigen::Matrix<T, 3, 1>& p_W_I,
                                    const Eigen::Matrix<T, 3, 1>& v_W_I, const T& delta,
                                    const PointMotion& motion, const Eigen::Vector3d& g_W) {
  using Mat3 = Eigen::Matrix<T, 3, 3>;
  using Vec3 = Eigen::Matrix<T, 3, 1>;
  const double dt = motion.dt_s;
  const Mat3 R_k = q_W_I.toRotationMatrix();
  PropagatedPose<T> pose;
  pose.R_W_I = R_k * motion.delta_q.toRotationMatrix().cast<T>() *
               (Mat3::Identity() + delta * geometry::Hat(motion.omega_rad_s.cast<T>()));
  const Vec3 v_t = v_W_I + (g_W * dt).cast<T>() + R_k * motion.delta_v.cast<T>();
  pose.p_W_I = p_W_I + v_W_I * T(dt) + (0.5 * g_W * dt * dt).cast<T>() +
               R_k * motion.delta_p.cast<T>() + delta * v_t;
  return pose;
}

// The same residual written once for any scalar: the autodiff twin used as the test oracle.
struct PointToPlaneResidual {
  PointToPlaneResidual(const PointToPlaneMeasurement& measurement, const Eigen::Vector3d& g_W)
      : m(measurement), g(g_W) {}

  template <typename T>
  bool operator()(const T* q_W_I_ptr, const T* p_W_I_ptr, const T* v_W_I_ptr, const T* q_I_L_ptr,
                  const T* p_I_L_ptr, const T* offset_ptr, T* residual) const {
    using Vec3 = Eigen::Matrix<T, 3, 1>;
    const Eigen::Map<const Eigen::Quaternion<T>> q_W_I(q_W_I_ptr);
    const Eigen::Map<const Vec3> p_W_I(p_W_I_ptr);
    const Eigen::Map<const Vec3> v_W_I(v_W_I_ptr);
    const Eigen::Map<const Eigen::Quaternion<T>> q_I_L(q_I_L_ptr);
    const Eigen::Map<const Vec3> p_I_L(p_I_L_ptr);
    const T delta = offset_ptr[0] - T(m.offset_linearization_s);
    const PropagatedPose<T> pose = PropagateKeyframe<T>(Eigen::Quaternion<T>(q_W_I), Vec3(p_W_I),
                                                        Vec3(v_W_I), delta, m.motion, g);
    const Vec3 p_W = pose.R_W_I * (q_I_L * m.p_L.cast<T>() + p_I_L) + pose.p_W_I;
    residual[0] = (m.plane.normal.cast<T>().dot(p_W) + T(m.plane.d)) / T(m.sigma_m);
    return true;
  }

  PointToPlaneMeasurement m;
  Eigen::Vector3d g;
};

// The autodiff twin as a cost function with the same parameter layout.
ceres::CostFunction* CreatePointToPlaneAutoDiff(const PointToPlaneMeasurement& measurement,
                                                const Eigen::Vector3d& g_W);

// A point measured by the LiDAR in W under the current estimate (Eq. P1-P3 at delta = 0),
// from the IMU pose at the point's instant, PropagateKeyframe(q_W_I, p_W_I, v_W_I, 0, motion,
// g_W): the points of one firing share it.
Eigen::Vector3d PointInWorld(const PropagatedPose<double>& pose, const Eigen::Quaterniond& q_I_L,
                             const Eigen::Vector3d& p_I_L, const Eigen::Vector3d& p_L);

}  // namespace factors
}  // namespace autocal
