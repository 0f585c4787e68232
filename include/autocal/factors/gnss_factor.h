#pragma once

// GNSS position factor (docs/factors.md, "GNSS factor"):
//   r = S (p_W_I + R_W_I p_I_A - p_W_A),   S = diag(1 / sigma_enu)            Eq. F30
// with p_W_A the fix converted to ENU (sensors::EnuConverter) and sigma_enu the receiver's
// per-fix standard deviations. Multipath outliers are left to the robust loss.
//
// Parameter blocks: q_W_I (4, RightQuaternionManifold), p_W_I (3), p_I_A (3, the lever arm).

#include <ceres/ceres.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "autocal/geometry/so3.h"
#include "autocal/sensors/gnss_enu.h"
#include "autocal/sensors/measurements.h"

namespace autocal {
namespace factors {

struct GnssMeasurement {
  Eigen::Vector3d p_W_A = Eigen::Vector3d::Zero();
  Eigen::Vector3d sigma_enu_m = Eigen::Vector3d::Ones();

  // Throws autocal::Error on a non-positive or non-finite sigma or an invalid position.
  static GnssMeasurement FromFix(const sensors::GnssFix& fix,
                                 const sensors::EnuConverter& converter);
};

class GnssFactor final : public ceres::SizedCostFunction<3, 4, 3, 3> {
 public:
  // Throws autocal::Error on a non-finite position or a non-positive sigma.
  explicit GnssFactor(const GnssMeasurement& measurement);
  static ceres::CostFunction* Create(const GnssMeasurement& measurement) {
    return new GnssFactor(measurement);
  }

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

 private:
  Eigen::Vector3d p_W_A_;
  Eigen::Vector3d inv_sigma_;
};

// Autodiff twin (test oracle).
class GnssResidual {
 public:
  explicit GnssResidual(const GnssMeasurement& measurement) : m_(measurement) {}
  static ceres::CostFunction* CreateAutoDiff(const GnssMeasurement& measurement) {
    return new ceres::AutoDiffCostFunction<GnssResidual, 3, 4, 3, 3>(new GnssResidual(measurement));
  }

  template <typename T>
  bool operator()(const T* q_W_I_ptr, const T* p_W_I_ptr, const T* p_I_A_ptr, T* residual) const {
    using Vec3 = geometry::Vector3<T>;
    const Eigen::Map<const Eigen::Quaternion<T>> q_W_I(q_W_I_ptr);
    const Eigen::Map<const Vec3> p_W_I(p_W_I_ptr), p_I_A(p_I_A_ptr);
    const Vec3 e = p_W_I + q_W_I * p_I_A - m_.p_W_A.cast<T>();
    for (int k = 0; k < 3; ++k) residual[k] = e(k) / T(m_.sigma_enu_m(k));
    return true;
  }

 private:
  GnssMeasurement m_;
};

}  // namespace factors
}  // namespace autocal
