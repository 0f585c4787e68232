#pragma once

// Keyframe factors whose measurement is read through the sensor's time offset, estimated in
// the solve (docs/keyframe_factors.md, Eq. K9): the measurement at keyframe time t_k is the
// sensor's series at t_k - offset on its own clock (TimeShiftedSeries), so the residual
// depends on the offset block through the series' slope.

#include <ceres/ceres.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <utility>

#include "autocal/geometry/so3.h"
#include "estimation/time_shifted_series.h"

namespace autocal {
namespace estimation {
namespace internal {

// The antenna position in ENU and its per-axis sigma, one row of the series per fix.
using GnssSeries = TimeShiftedSeries<6>;

// Eq. F30 with p_W_A and sigma read at t_k - offset_gnss. Parameter blocks: q_W_I (4,
// RightQuaternionManifold), p_W_I (3), p_I_A (3), time_offset_gnss_imu_s (1).
class ShiftedGnssResidual {
 public:
  ShiftedGnssResidual(std::shared_ptr<const GnssSeries> series, int64_t t_ns)
      : series_(std::move(series)), t_ns_(t_ns) {}

  static ceres::CostFunction* Create(std::shared_ptr<const GnssSeries> series, int64_t t_ns) {
    return new ceres::AutoDiffCostFunction<ShiftedGnssResidual, 3, 4, 3, 3, 1>(
        new ShiftedGnssResidual(std::move(series), t_ns));
  }

  template <typename T>
  bool operator()(const T* q_W_I_ptr, const T* p_W_I_ptr, const T* p_I_A_ptr, const T* offset_s,
                  T* residual) const {
    using Vec3 = geometry::Vector3<T>;
    const Eigen::Map<const Eigen::Quaternion<T>> q_W_I(q_W_I_ptr);
    const Eigen::Map<const Vec3> p_W_I(p_W_I_ptr), p_I_A(p_I_A_ptr);
    const Eigen::Matrix<T, 6, 1> fix = series_->At(t_ns_, offset_s[0]);
    const Vec3 e = p_W_I + q_W_I * p_I_A - fix.template head<3>();
    // The sigma weights the row; its slope in the offset is not information about it.
    for (int k = 0; k < 3; ++k) residual[k] = e(k) / T(ScalarPart(fix(3 + k)));
    return true;
  }

 private:
  std::shared_ptr<const GnssSeries> series_;
  int64_t t_ns_;
};

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
