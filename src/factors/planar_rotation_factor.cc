#include "autocal/factors/planar_rotation_factor.h"

#include <cmath>

#include "autocal/common/error.h"
#include "autocal/geometry/manifolds.h"
#include "autocal/geometry/so3.h"

namespace autocal {
namespace factors {

PlanarRotationFactor::PlanarRotationFactor(const PlanarRotationMeasurement& measurement)
    : gyro_(measurement.gyro_rad_s), inv_sigma_(1.0 / measurement.sigma_rad_s) {
  if (!gyro_.allFinite()) throw Error("planar-rotation factor: the gyro reading is not finite");
  if (!std::isfinite(measurement.sigma_rad_s) || !(measurement.sigma_rad_s > 0.0)) {
    throw Error("planar-rotation factor: the roll and pitch rate sigma must be positive");
  }
}

bool PlanarRotationFactor::Evaluate(double const* const* parameters, double* residuals,
                                    double** jacobians) const {
  const Eigen::Map<const Eigen::Vector3d> b_g(parameters[0]);
  const Eigen::Map<const Eigen::Quaterniond> q_I_V(parameters[1]);
  const Eigen::Matrix3d R_I_V = q_I_V.toRotationMatrix();
  const Eigen::Vector3d w_V = R_I_V.transpose() * (gyro_ - b_g);
  Eigen::Map<Eigen::Vector2d> r(residuals);
  r = inv_sigma_ * w_V.head<2>();  // Eq. F27
  if (jacobians == nullptr) return true;
  // d w_V / d b_g = -R_I_V^T; d w_V / d(right tangent of q_I_V) = Hat(w_V).
  if (jacobians[0] != nullptr) {
    Eigen::Map<Eigen::Matrix<double, 2, 3, Eigen::RowMajor>> j(jacobians[0]);
    j = -inv_sigma_ * R_I_V.transpose().topRows<2>();
  }
  if (jacobians[1] != nullptr) {
    const Eigen::Matrix<double, 2, 3> j_tangent =
        ProjectOutMountYaw(inv_sigma_ * geometry::Hat(w_V).topRows<2>());  // Eq. F27b
    Eigen::Map<Eigen::Matrix<double, 2, 4, Eigen::RowMajor>> j(jacobians[1]);
    j = geometry::LiftTangentJacobian<2>(j_tangent, parameters[1]);
  }
  return true;
}

}  // namespace factors
}  // namespace autocal
