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
#include <vector>

#include "autocal/factors/gnss_factor.h"
#include "autocal/factors/wheel_factor.h"
#include "autocal/geometry/so3.h"
#include "autocal/sensors/sensor_config.h"
#include "estimation/time_shifted_series.h"

namespace autocal {
namespace estimation {
namespace internal {

// The antenna position in ENU and its per-axis sigma, one row of the series per fix.
using GnssSeries = TimeShiftedSeries<6>;

// Eq. F30 with p_W_A and sigma read at t_k - offset_gnss, the rows of `axes`. Parameter
// blocks: q_W_I (4, RightQuaternionManifold), p_W_I (3), p_I_A (3), time_offset_gnss_imu_s (1).
class ShiftedGnssResidual {
 public:
  ShiftedGnssResidual(std::shared_ptr<const GnssSeries> series, int64_t t_ns,
                      factors::GnssAxes axes = factors::GnssAxes::kAll)
      : series_(std::move(series)), t_ns_(t_ns), axes_(axes) {}

  static ceres::CostFunction* Create(std::shared_ptr<const GnssSeries> series, int64_t t_ns,
                                     factors::GnssAxes axes = factors::GnssAxes::kAll) {
    return new ceres::AutoDiffCostFunction<ShiftedGnssResidual, ceres::DYNAMIC, 4, 3, 3, 1>(
        new ShiftedGnssResidual(std::move(series), t_ns, axes), factors::NumRows(axes));
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
    const int first = factors::FirstRow(axes_);
    for (int k = 0; k < factors::NumRows(axes_); ++k) {
      residual[k] = e(first + k) / T(ScalarPart(fix(3 + first + k)));
    }
    return true;
  }

 private:
  std::shared_ptr<const GnssSeries> series_;
  int64_t t_ns_;
  factors::GnssAxes axes_;
};

// The wheel data of any form as two values per sample: left and right angular rates (rad/s),
// left and right rear speeds (m/s), or the controller's speed (m/s) and yaw rate (rad/s).
using WheelSeries = TimeShiftedSeries<2>;

// How a form's two values and its intrinsic blocks give the rear axle's speed and yaw rate.
struct ShiftedWheelForm {
  sensors::WheelForm form = sensors::WheelForm::kAngularRates;
  bool shared_radius = false;       // angular rates: one radius block for both wheels
  double controller_track_m = 1.0;  // speed and yaw rate: b_ctrl

  // Intrinsic blocks (1 double each) between p_I_V and the offset: r_l, r_r (or one shared r),
  // b for angular rates; s_l, s_r, b for linear speeds; k_v, b_eff for speed and yaw rate.
  int NumIntrinsics() const {
    if (form == sensors::WheelForm::kSpeedYawRate) return 2;
    return form == sensors::WheelForm::kAngularRates && shared_radius ? 2 : 3;
  }
};

// Eq. F22 with the wheel values read at t_k - offset_wheel (Eq. K9) and the raw gyro at t_k on
// the IMU clock (the state's own instant): the residuals of WheelResidual (angular rates,
// Eq. F20), WheelSpeedResidual (Eq. F25) and OdometryTwistResidual (Eq. F26) through their
// shared pieces PredictVehicleMotion and WheelRows. Parameter blocks: q_W_I (4,
// RightQuaternionManifold), v_W_I (3), b_g (3), q_I_V (4, RightQuaternionManifold), p_I_V (3),
// the form's intrinsics (ShiftedWheelForm::NumIntrinsics, 1 each), time_offset_wheel_imu_s (1).
// Residuals as WheelResidual: 4 with the non-holonomic rows, else 2.
class ShiftedWheelResidual {
 public:
  ShiftedWheelResidual(std::shared_ptr<const WheelSeries> series, int64_t t_ns,
                       const Eigen::Vector3d& gyro_rad_s, const ShiftedWheelForm& form,
                       const factors::WheelFactorOptions& options)
      : series_(std::move(series)),
        t_ns_(t_ns),
        gyro_rad_s_(gyro_rad_s),
        form_(form),
        options_(options) {}

  static constexpr int kStride = 4;
  static ceres::CostFunction* Create(std::shared_ptr<const WheelSeries> series, int64_t t_ns,
                                     const Eigen::Vector3d& gyro_rad_s,
                                     const ShiftedWheelForm& form,
                                     const factors::WheelFactorOptions& options) {
    auto* cost = new ceres::DynamicAutoDiffCostFunction<ShiftedWheelResidual, kStride>(
        new ShiftedWheelResidual(std::move(series), t_ns, gyro_rad_s, form, options));
    for (int size : {4, 3, 3, 4, 3}) cost->AddParameterBlock(size);
    for (int i = 0; i < form.NumIntrinsics(); ++i) cost->AddParameterBlock(1);
    cost->AddParameterBlock(1);
    cost->SetNumResiduals(options.non_holonomic ? 4 : 2);
    return cost;
  }

  // False (an invalid step) for a non-positive track or effective track.
  template <typename T>
  bool operator()(T const* const* p, T* residual) const {
    const int n = form_.NumIntrinsics();
    const Eigen::Matrix<T, 2, 1> x = series_->At(t_ns_, p[5 + n][0]);
    T speed, yaw_rate;
    const T& track = form_.form == sensors::WheelForm::kSpeedYawRate ? p[6][0] : p[4 + n][0];
    if (!(track > T(0.0))) return false;
    if (form_.form == sensors::WheelForm::kSpeedYawRate) {
      const T& k_v = p[5][0];
      speed = k_v * x(0);
      yaw_rate = k_v * x(1) * T(form_.controller_track_m) / track;  // track: b_eff
    } else {
      const T& scale_left = p[5][0];
      const T& scale_right = n == 2 ? p[5][0] : p[6][0];
      const T left = x(0) * scale_left;
      const T right = x(1) * scale_right;
      speed = T(0.5) * (left + right);
      yaw_rate = (right - left) / track;
    }
    const factors::VehicleMotion<T> motion =
        factors::PredictVehicleMotion(p[0], p[1], p[2], p[3], p[4], gyro_rad_s_);
    factors::WheelRows(motion, speed, yaw_rate, track, options_, residual);
    return true;
  }

 private:
  std::shared_ptr<const WheelSeries> series_;
  int64_t t_ns_;
  Eigen::Vector3d gyro_rad_s_;
  ShiftedWheelForm form_;
  factors::WheelFactorOptions options_;
};

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
