#pragma once

// Planar-rotation factor (docs/factors.md, "Planar rotation"): a ground vehicle turns
// about its own up axis, so its roll and pitch rates in V are only what the ground and the
// body add, zero-mean and unrelated to the yaw rate:
//   w_V = R_I_V^T (w - b_g),   r = [w_V.x, w_V.y] / sigma                           Eq. F27
// with w the gyro reading at the keyframe. A mount tilted by d makes w_V.x, w_V.y follow the yaw
// rate by d, so turns determine the mount's roll and pitch (first order), where the yaw-rate
// row of the wheel factor sees the tilt only through cos(d).
//
// The mount's yaw (a turn of q_I_V about V's z) turns r and keeps |r|: the rows say nothing
// about it, and one sigma for both rows keeps it so. The Jacobian along that direction, the
// residual turned by 90 degrees, is left out (Eq. F27b): its product with r is zero, so the
// gradient is the cost's own, but its square would count the rates' noise as information on
// the yaw.
//
// Parameter blocks: b_g (3), q_I_V (4, RightQuaternionManifold).

#include <ceres/ceres.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace autocal {
namespace factors {

struct PlanarRotationMeasurement {
  Eigen::Vector3d gyro_rad_s = Eigen::Vector3d::Zero();  // reading at the keyframe, IMU frame
  double sigma_rad_s = 1.0;  // of the roll and pitch rates in V, one for both
};

class PlanarRotationFactor final : public ceres::SizedCostFunction<2, 3, 4> {
 public:
  // Throws autocal::Error on a non-finite reading or a non-positive sigma.
  explicit PlanarRotationFactor(const PlanarRotationMeasurement& measurement);
  static ceres::CostFunction* Create(const PlanarRotationMeasurement& measurement) {
    return new PlanarRotationFactor(measurement);
  }

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

 private:
  Eigen::Vector3d gyro_;
  double inv_sigma_;
};

// Autodiff twin (test oracle) of the residual; its q_I_V Jacobian keeps the yaw direction that
// PlanarRotationFactor leaves out (compare them with ProjectOutMountYaw).
class PlanarRotationResidual {
 public:
  explicit PlanarRotationResidual(const PlanarRotationMeasurement& m) : m_(m) {}
  static ceres::CostFunction* CreateAutoDiff(const PlanarRotationMeasurement& m) {
    return new ceres::AutoDiffCostFunction<PlanarRotationResidual, 2, 3, 4>(
        new PlanarRotationResidual(m));
  }

  template <typename T>
  bool operator()(const T* b_g_ptr, const T* q_I_V_ptr, T* residual) const {
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> b_g(b_g_ptr);
    const Eigen::Map<const Eigen::Quaternion<T>> q_I_V(q_I_V_ptr);
    const Eigen::Matrix<T, 3, 1> w_V = q_I_V.conjugate() * (m_.gyro_rad_s.cast<T>() - b_g);
    residual[0] = w_V.x() / T(m_.sigma_rad_s);
    residual[1] = w_V.y() / T(m_.sigma_rad_s);
    return true;
  }

 private:
  PlanarRotationMeasurement m_;
};

// Eq. F27b on a Jacobian in the right tangent space of q_I_V: its column along V's z set to zero.
inline Eigen::Matrix<double, 2, 3> ProjectOutMountYaw(Eigen::Matrix<double, 2, 3> j_tangent) {
  j_tangent.col(2).setZero();
  return j_tangent;
}

}  // namespace factors
}  // namespace autocal
