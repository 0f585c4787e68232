#pragma once

// IMU preintegration factor between keyframes i and j (docs/factors.md, "IMU factor").
//
//   r_phi = Log( dR(b_g_i)^T R_i^T R_j )                              Eq. F10
//   r_v   = R_i^T (v_j - v_i - g dt) - dv(b_g_i, b_a_i)
//   r_p   = R_i^T (p_j - p_i - v_i dt - g dt^2 / 2) - dp(b_g_i, b_a_i)
//   r_bg  = b_g_j - b_g_i,   r_ba = b_a_j - b_a_i
// with the first-order bias-corrected deltas of Eq. F7, whitened by the square root of the
// inverse preintegration covariance (Eq. F5): residual = U r, U^T U = Cov^-1.
//
// Parameter blocks (DESIGN.md, one block per state component, so that each can be held
// constant or marginalized on its own):
//   q_W_I_i (4, RightQuaternionManifold), p_W_I_i (3), v_W_I_i (3), b_g_i (3), b_a_i (3),
//   q_W_I_j (4, RightQuaternionManifold), p_W_I_j (3), v_W_I_j (3), b_g_j (3), b_a_j (3).
//
// The factor copies what it needs from the preintegration, so it is immutable and safe
// to evaluate from several threads. When ImuPreintegration::ReintegrateIfNeeded() moved
// the linearization biases, the estimator replaces the residual block with a new factor.

#include <ceres/ceres.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "autocal/geometry/so3.h"
#include "autocal/sensors/imu_preintegration.h"

namespace autocal {
namespace factors {

// What the IMU residual needs from a preintegration.
struct ImuDeltaMeasurement {
  explicit ImuDeltaMeasurement(const sensors::ImuPreintegration& pim);

  double dt_s;
  sensors::LinearizedDeltas deltas;  // corrected for the biases of keyframe i (Eq. F7)
  Eigen::Vector3d g_W;
  sensors::Matrix15d sqrt_information;  // lower triangular
};

// Analytic Jacobians (Eq. F11), reported on the right (body-frame) tangent of the
// quaternion blocks and lifted with geometry::LiftTangentJacobian.
class ImuFactor final : public ceres::SizedCostFunction<15, 4, 3, 3, 3, 3, 4, 3, 3, 3, 3> {
 public:
  explicit ImuFactor(const sensors::ImuPreintegration& pim) : m_(pim) {}
  static ceres::CostFunction* Create(const sensors::ImuPreintegration& pim) {
    return new ImuFactor(pim);
  }

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

  const ImuDeltaMeasurement& measurement() const { return m_; }

 private:
  ImuDeltaMeasurement m_;
};

// The same residual written once for double and ceres::Jet: the autodiff twin that tests
// use as the oracle of ImuFactor's Jacobians.
class ImuResidual {
 public:
  explicit ImuResidual(const sensors::ImuPreintegration& pim) : m_(pim) {}

  static ceres::CostFunction* CreateAutoDiff(const sensors::ImuPreintegration& pim) {
    return new ceres::AutoDiffCostFunction<ImuResidual, 15, 4, 3, 3, 3, 3, 4, 3, 3, 3, 3>(
        new ImuResidual(pim));
  }

  template <typename T>
  bool operator()(const T* q_i_ptr, const T* p_i_ptr, const T* v_i_ptr, const T* bg_i_ptr,
                  const T* ba_i_ptr, const T* q_j_ptr, const T* p_j_ptr, const T* v_j_ptr,
                  const T* bg_j_ptr, const T* ba_j_ptr, T* residual_ptr) const {
    using Vec3 = geometry::Vector3<T>;
    const Eigen::Map<const Eigen::Quaternion<T>> q_i(q_i_ptr), q_j(q_j_ptr);
    const Eigen::Map<const Vec3> p_i(p_i_ptr), v_i(v_i_ptr), bg_i(bg_i_ptr), ba_i(ba_i_ptr);
    const Eigen::Map<const Vec3> p_j(p_j_ptr), v_j(v_j_ptr), bg_j(bg_j_ptr), ba_j(ba_j_ptr);
    Eigen::Quaternion<T> dq;
    Vec3 dv, dp;
    m_.deltas.Corrected(Vec3(bg_i), Vec3(ba_i), &dq, &dv, &dp);
    const T dt(m_.dt_s);
    const Vec3 g = m_.g_W.cast<T>();
    const Eigen::Quaternion<T> q_i_inv = q_i.conjugate();
    Eigen::Matrix<T, 15, 1> r;
    r.template segment<3>(0) = geometry::Log(Eigen::Quaternion<T>(dq.conjugate() * q_i_inv * q_j));
    r.template segment<3>(3) = q_i_inv * Vec3(v_j - v_i - g * dt) - dv;
    r.template segment<3>(6) = q_i_inv * Vec3(p_j - p_i - v_i * dt - T(0.5) * g * dt * dt) - dp;
    r.template segment<3>(9) = bg_j - bg_i;
    r.template segment<3>(12) = ba_j - ba_i;
    Eigen::Map<Eigen::Matrix<T, 15, 1>> residual(residual_ptr);
    residual = m_.sqrt_information.cast<T>() * r;
    return true;
  }

 private:
  ImuDeltaMeasurement m_;
};

}  // namespace factors
}  // namespace autocal
