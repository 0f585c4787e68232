#pragma once

// Keyframe factors of a sensor on a clock of its own, whose time offset the solve estimates
// (docs/keyframe_factors.md, "Sensor clocks"). With the project's sign, t_imu = t_sensor +
// offset, a sample stamped t_j was taken at IMU time t_j + offset: the keyframe's state is
// carried there, delta = t_j + offset - t_k after it, by the IMU (Eq. K16),
//   w(delta) = w + w' delta,                       w = gyro - b_g
//   R(delta) = R_k Exp(w delta + w' delta^2 / 2)
//   a_W      = R_k (accel - b_a) + g_W
//   v(delta) = v_k + a_W delta
//   p(delta) = p_k + v_k delta + a_W delta^2 / 2
// with the raw gyro, its slope w' and the raw specific force read around t_k
// (ImuAroundKeyframe). The sample stays as it was measured, so the residual is smooth in the
// offset and its derivative the state's own rates: the solver's model is the cost's. Reading
// the sample at t_k - offset instead (interpolating the samples) made the cost piecewise
// linear in the offset with a Jacobian of the samples' noise, and the clocks ended where the
// solve started them.

#include <ceres/ceres.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <vector>

#include "autocal/common/time.h"
#include "autocal/factors/gnss_factor.h"
#include "autocal/factors/wheel_factor.h"
#include "autocal/geometry/so3.h"
#include "autocal/sensors/measurements.h"
#include "autocal/sensors/sensor_config.h"

namespace autocal {
namespace estimation {
namespace internal {

// What the IMU says around a keyframe's instant, to carry its state a short time (Eq. K16).
struct ImuAroundKeyframe {
  Eigen::Vector3d gyro_rad_s = Eigen::Vector3d::Zero();         // raw, at t_k
  Eigen::Vector3d gyro_slope_rad_s2 = Eigen::Vector3d::Zero();  // d(gyro)/dt at t_k
  Eigen::Vector3d accel_m_s2 = Eigen::Vector3d::Zero();         // raw specific force at t_k
  Eigen::Vector3d g_W = Eigen::Vector3d::Zero();                // gravity in W
};

// Half the span of the least-squares lines through the IMU samples that give the gyro, its
// slope and the specific force at t_k. A slope from two samples would be mostly noise (283
// sigma per second at 200 Hz); over +-0.1 s it is 2.6 sigma per second, and the line still
// follows the body's sway on its suspension. Over +-0.5 s the lines smoothed that sway away
// and biased the wheel clock of the noise-free 30 s urban drive by -0.14 ms, over +-0.1 s
// by -0.02 ms.
constexpr double kImuLineHalfWidthS = 0.1;

// The IMU around t_ns: the lines through the samples within kImuLineHalfWidthS of it (at least
// two on each side where the log has them), evaluated at t_ns. Gravity g_W = (0, 0,
// -gravity_m_s2). Empty when two of those samples lie more than max_gap_ns apart (an IMU
// dropout) or t_ns is outside the samples. Throws autocal::Error for fewer than two samples.
std::optional<ImuAroundKeyframe> ImuAround(const sensors::ImuSamples& imu, int64_t t_ns,
                                           double gravity_m_s2, int64_t max_gap_ns);

template <typename T>
struct CarriedState {
  Eigen::Quaternion<T> q_W_I;
  geometry::Vector3<T> v_W_I, w_I;  // w_I bias-corrected
  geometry::Vector3<T> a_W;         // the acceleration in W the carry assumes
};

// Eq. K16 for the keyframe's attitude, velocity and body rate (q_W_I, v_W_I, b_g, b_a) delta_s
// after t_k.
template <typename T>
CarriedState<T> CarryState(const T* q_W_I_ptr, const T* v_W_I_ptr, const T* b_g_ptr,
                           const T* b_a_ptr, const ImuAroundKeyframe& imu, const T& delta_s) {
  using Vec3 = geometry::Vector3<T>;
  const Eigen::Map<const Eigen::Quaternion<T>> q_k(q_W_I_ptr);
  const Eigen::Map<const Vec3> v_k(v_W_I_ptr), b_g(b_g_ptr), b_a(b_a_ptr);
  const Vec3 w = imu.gyro_rad_s.cast<T>() - b_g;
  const Vec3 w_slope = imu.gyro_slope_rad_s2.cast<T>();
  CarriedState<T> s;
  s.a_W = q_k * Vec3(imu.accel_m_s2.cast<T>() - b_a) + imu.g_W.cast<T>();
  s.q_W_I = q_k * geometry::Exp(Vec3(w * delta_s + T(0.5) * w_slope * delta_s * delta_s));
  s.v_W_I = v_k + s.a_W * delta_s;
  s.w_I = w + w_slope * delta_s;
  return s;
}

// Eq. K16 for the position: p_k + v_k delta_s + a_W delta_s^2 / 2, with the carry's a_W.
template <typename T>
geometry::Vector3<T> CarryPosition(const T* p_W_I_ptr, const T* v_W_I_ptr,
                                   const CarriedState<T>& carried, const T& delta_s) {
  using Vec3 = geometry::Vector3<T>;
  const Eigen::Map<const Vec3> p_k(p_W_I_ptr), v_k(v_W_I_ptr);
  return p_k + v_k * delta_s + T(0.5) * carried.a_W * delta_s * delta_s;
}

// Eq. F30 for the fix stamped t_fix_ns (p_W_A, per-axis sigma), the rows of `axes`, against
// keyframe k's antenna carried to the fix's IMU time. Parameter blocks: q_W_I (4,
// RightQuaternionManifold), p_W_I, v_W_I, b_g, b_a (3 each), p_I_A (3),
// time_offset_gnss_imu_s (1).
class ShiftedGnssResidual {
 public:
  ShiftedGnssResidual(const factors::GnssMeasurement& fix, int64_t t_fix_ns, int64_t t_k_ns,
                      const ImuAroundKeyframe& imu, factors::GnssAxes axes)
      : fix_(fix), fix_after_keyframe_s_(NsToSeconds(t_fix_ns - t_k_ns)), imu_(imu), axes_(axes) {}

  // The cost function Create returns (callers tell the factor by it).
  using Cost =
      ceres::AutoDiffCostFunction<ShiftedGnssResidual, ceres::DYNAMIC, 4, 3, 3, 3, 3, 3, 1>;
  static ceres::CostFunction* Create(const factors::GnssMeasurement& fix, int64_t t_fix_ns,
                                     int64_t t_k_ns, const ImuAroundKeyframe& imu,
                                     factors::GnssAxes axes = factors::GnssAxes::kAll) {
    return new Cost(new ShiftedGnssResidual(fix, t_fix_ns, t_k_ns, imu, axes),
                    factors::NumRows(axes));
  }

  template <typename T>
  bool operator()(const T* q_W_I, const T* p_W_I, const T* v_W_I, const T* b_g, const T* b_a,
                  const T* p_I_A_ptr, const T* offset_s, T* residual) const {
    using Vec3 = geometry::Vector3<T>;
    const T delta_s = T(fix_after_keyframe_s_) + offset_s[0];
    const CarriedState<T> s = CarryState(q_W_I, v_W_I, b_g, b_a, imu_, delta_s);
    const Eigen::Map<const Vec3> p_I_A(p_I_A_ptr);
    const Vec3 e = CarryPosition(p_W_I, v_W_I, s, delta_s) + s.q_W_I * p_I_A - fix_.p_W_A.cast<T>();
    const int first = factors::FirstRow(axes_);
    for (int k = 0; k < factors::NumRows(axes_); ++k) {
      residual[k] = e(first + k) / T(fix_.sigma_enu_m(first + k));
    }
    return true;
  }

 private:
  factors::GnssMeasurement fix_;
  double fix_after_keyframe_s_;  // t_fix - t_k
  ImuAroundKeyframe imu_;
  factors::GnssAxes axes_;
};

// How a wheel form's two values and its intrinsic blocks give the rear axle's speed and yaw
// rate: left and right angular rates (rad/s), left and right rear speeds (m/s), or the
// controller's speed (m/s) and yaw rate (rad/s).
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

// A wheel sample as a keyframe's factor takes it (Eq. K17): the form's two values, its stamp
// on the wheel clock, the offset it was paired at, and the body rate the rows take at the
// instant it was taken then (the raw gyro as the rows read it, Eq. K13 and K14, bias
// included).
struct PairedWheelSample {
  Eigen::Vector2d values = Eigen::Vector2d::Zero();
  int64_t t_ns = 0;
  double paired_offset_s = 0.0;
  Eigen::Vector3d gyro_rad_s = Eigen::Vector3d::Zero();
};

// Eq. F22 for a wheel sample against keyframe k's state carried to the sample's IMU time (Eq. K16):
// the residuals of WheelResidual (angular rates, Eq. F20), WheelSpeedResidual (Eq. F25) and
// OdometryTwistResidual (Eq. F26) through their shared pieces PredictVehicleMotion, AxleFromWheels
// or AxleFromTwist, and WheelRows. The rows take the sample's body rate, carried along the gyro's
// slope as the offset moves from the one it was paired at, so the gyro's noise enters them once, as
// the rate's covariance in their sigma says. The non-holonomic rows hold the state at the paired
// instant: they read no wheel value, and carried with the offset their model error (the body's sway
// on its suspension, which follows the acceleration) would pull on it. Parameter blocks: q_W_I (4,
// RightQuaternionManifold), v_W_I, b_g, b_a (3 each), q_I_V (4, RightQuaternionManifold), p_I_V
// (3), the form's intrinsics (ShiftedWheelForm::NumIntrinsics, 1 each), time_offset_wheel_imu_s
// (1). Residuals as WheelResidual: 4 with the non-holonomic rows, else 2.
class ShiftedWheelResidual {
 public:
  ShiftedWheelResidual(const PairedWheelSample& sample, int64_t t_k_ns,
                       const ImuAroundKeyframe& imu, const ShiftedWheelForm& form,
                       const factors::WheelFactorOptions& options)
      : sample_(sample),
        sample_after_keyframe_s_(NsToSeconds(sample.t_ns - t_k_ns)),
        imu_(imu),
        form_(form),
        options_(options) {}

  static constexpr int kStride = 4;
  // The cost function Create returns (callers tell the factor by it).
  using Cost = ceres::DynamicAutoDiffCostFunction<ShiftedWheelResidual, kStride>;
  static ceres::CostFunction* Create(const PairedWheelSample& sample, int64_t t_k_ns,
                                     const ImuAroundKeyframe& imu, const ShiftedWheelForm& form,
                                     const factors::WheelFactorOptions& options) {
    auto* cost = new Cost(new ShiftedWheelResidual(sample, t_k_ns, imu, form, options));
    for (int size : {4, 3, 3, 3, 4, 3}) cost->AddParameterBlock(size);
    for (int i = 0; i < form.NumIntrinsics(); ++i) cost->AddParameterBlock(1);
    cost->AddParameterBlock(1);
    cost->SetNumResiduals(options.non_holonomic ? 4 : 2);
    return cost;
  }

  // False (an invalid step) for a non-positive track or effective track.
  template <typename T>
  bool operator()(T const* const* p, T* residual) const {
    using Vec3 = geometry::Vector3<T>;
    constexpr int kIntrinsics = 6;  // the first intrinsic block
    const int n = form_.NumIntrinsics();
    const T& track = p[kIntrinsics + n - 1][0];
    if (!(track > T(0.0))) return false;
    const factors::AxleMotion<T> axle = WheelMotion(p + kIntrinsics, track);
    const T paired_delta_s(sample_after_keyframe_s_ + sample_.paired_offset_s);
    const T delta_s = T(sample_after_keyframe_s_) + p[kIntrinsics + n][0];
    const Vec3 w_paired = sample_.gyro_rad_s.cast<T>() - Eigen::Map<const Vec3>(p[2]);
    const Vec3 w = w_paired + imu_.gyro_slope_rad_s2.cast<T>() * (delta_s - paired_delta_s);
    const CarriedState<T> s = CarryState(p[0], p[1], p[2], p[3], imu_, delta_s);
    factors::WheelRows(factors::PredictVehicleMotion(s.q_W_I, s.v_W_I, w, p[4], p[5]), axle.speed,
                       axle.yaw_rate, track, options_, residual);
    if (options_.non_holonomic) {
      const CarriedState<T> at = CarryState(p[0], p[1], p[2], p[3], imu_, paired_delta_s);
      T paired[4];
      factors::WheelRows(factors::PredictVehicleMotion(at.q_W_I, at.v_W_I, w_paired, p[4], p[5]),
                         axle.speed, axle.yaw_rate, track, options_, paired);
      residual[2] = paired[2];
      residual[3] = paired[3];
    }
    return true;
  }

 private:
  // The rear axle's speed and yaw rate the wheels report through the form's intrinsics.
  template <typename T>
  factors::AxleMotion<T> WheelMotion(T const* const* intrinsics, const T& track) const {
    if (form_.form == sensors::WheelForm::kSpeedYawRate) {  // track: b_eff
      return factors::AxleFromTwist(intrinsics[0][0], sample_.values(0), sample_.values(1),
                                    form_.controller_track_m, track);
    }
    const T& scale_left = intrinsics[0][0];
    const T& scale_right = form_.NumIntrinsics() == 2 ? intrinsics[0][0] : intrinsics[1][0];
    return factors::AxleFromWheels(T(sample_.values(0)) * scale_left,
                                   T(sample_.values(1)) * scale_right, track);
  }

  PairedWheelSample sample_;
  double sample_after_keyframe_s_;  // t_sample - t_k
  ImuAroundKeyframe imu_;
  ShiftedWheelForm form_;
  factors::WheelFactorOptions options_;
};

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
