#pragma once

// GNSS position factor (docs/factors.md, "GNSS factor"):
//   r = S (p_W_I + R_W_I p_I_A - p_W_A),   S = diag(1 / sigma_enu)            Eq. F30
// with p_W_A the fix converted to ENU (sensors::EnuConverter) and sigma_enu the receiver's
// per-fix standard deviations. Multipath outliers are left to the robust loss.
//
// A factor carries the rows of GnssAxes. A fix's horizontal and vertical errors are separate
// processes (the receiver states them apart; the satellite geometry and the atmosphere weigh
// on the vertical most), so the estimators give each its own residual block and robust loss:
// an altitude outlier does not discard the fix's horizontal position, nor a horizontal
// multipath jump its altitude.
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

// The ENU rows of Eq. F30 a factor carries: all three, east and north, or up.
enum class GnssAxes { kAll, kHorizontal, kVertical };
inline int FirstRow(GnssAxes axes) { return axes == GnssAxes::kVertical ? 2 : 0; }
inline int NumRows(GnssAxes axes) {
  return axes == GnssAxes::kAll ? 3 : (axes == GnssAxes::kHorizontal ? 2 : 1);
}

class GnssFactor final : public ceres::CostFunction {
 public:
  // Throws autocal::Error on a non-finite position or a non-positive sigma.
  explicit GnssFactor(const GnssMeasurement& measurement, GnssAxes axes = GnssAxes::kAll);
  static ceres::CostFunction* Create(const GnssMeasurement& measurement,
                                     GnssAxes axes = GnssAxes::kAll) {
    return new GnssFactor(measurement, axes);
  }

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

 private:
  Eigen::Vector3d p_W_A_;
  Eigen::Vector3d inv_sigma_;
  int first_row_;
};

// Autodiff twin (test oracle).
class GnssResidual {
 public:
  explicit GnssResidual(const GnssMeasurement& measurement, GnssAxes axes = GnssAxes::kAll)
      : m_(measurement), axes_(axes) {}
  static ceres::CostFunction* CreateAutoDiff(const GnssMeasurement& measurement,
                                             GnssAxes axes = GnssAxes::kAll) {
    return new ceres::AutoDiffCostFunction<GnssResidual, ceres::DYNAMIC, 4, 3, 3>(
        new GnssResidual(measurement, axes), NumRows(axes));
  }

  template <typename T>
  bool operator()(const T* q_W_I_ptr, const T* p_W_I_ptr, const T* p_I_A_ptr, T* residual) const {
    using Vec3 = geometry::Vector3<T>;
    const Eigen::Map<const Eigen::Quaternion<T>> q_W_I(q_W_I_ptr);
    const Eigen::Map<const Vec3> p_W_I(p_W_I_ptr), p_I_A(p_I_A_ptr);
    const Vec3 e = p_W_I + q_W_I * p_I_A - m_.p_W_A.cast<T>();
    const int first = FirstRow(axes_);
    for (int k = 0; k < NumRows(axes_); ++k) {
      residual[k] = e(first + k) / T(m_.sigma_enu_m(first + k));
    }
    return true;
  }

 private:
  GnssMeasurement m_;
  GnssAxes axes_;
};

}  // namespace factors
}  // namespace autocal
