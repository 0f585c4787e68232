#pragma once

// Planar-rotation factor (docs/factors.md, "Planar-rotation factor"): a ground vehicle turns
// about its own up axis, so its roll and pitch rates in V are only what the ground and the
// body add, zero-mean and unrelated to the yaw rate:
//   w_V = R_I_V^T (w - b_g),   r = [w_V.x / sigma_x, w_V.y / sigma_y]                 Eq. F27
// with w the gyro reading at the keyframe. A mount tilted by d makes w_V.x, w_V.y follow the yaw
// rate by d, so turns determine the mount's roll and pitch (first order), where the yaw-rate
// row of the wheel factor sees the tilt only through cos(d).
//
// Parameter blocks: b_g (3), q_I_V (4, RightQuaternionManifold).

#include <ceres/ceres.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace autocal {
namespace factors {

struct PlanarRotationMeasurement {
  Eigen::Vector3d gyro_rad_s = Eigen::Vector3d::Zero();   // reading at the keyframe, IMU frame
  Eigen::Vector2d sigma_rad_s = Eigen::Vector2d::Ones();  // of the roll and pitch rates in V
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
  Eigen::Vector2d inv_sigma_;
};

// Autodiff twin (test oracle).
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
    residual[0] = w_V.x() / T(m_.sigma_rad_s.x());
    residual[1] = w_V.y() / T(m_.sigma_rad_s.y());
    return true;
  }

 private:
  PlanarRotationMeasurement m_;
};

}  // namespace factors
}  // namespace autocal
