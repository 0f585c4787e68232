#pragma once

// Wheel factors (docs/factors.md, "Wheel-encoder factor" and "Wheel forms"): the state's
// vehicle-frame speed and yaw rate (PredictVehicleMotion, Eq. F21) against the wheel data in
// the form the vehicle reports them: angular rates times radii (WheelFactor, WheelResidual),
// linear speeds times speed scales (WheelSpeedResidual, Eq. F25) or the controller's speed and
// yaw rate (OdometryTwistResidual, Eq. F26).
//
// The wheel rates give the forward speed and yaw rate of the rear-axle centre V
// (Eq. F20):  v_wheel = (w_l r_l + w_r r_r) / 2,   yaw_wheel = (w_r r_r - w_l r_l) / b.
// The state predicts them through T_I_V (Eq. F21): with w_I = gyro - b_g the bias-corrected
// body rate at the same instant,
//   v_V = R_I_V^T (R_W_I^T v_W_I + w_I x p_I_V),    w_V = R_I_V^T w_I,
// and the residual is (Eq. F22)
//   r = [ (v_V.x - v_wheel) / s_v,  (w_V.z - yaw_wheel) / s_yaw,  v_V.y / s_lat,  v_V.z / s_vert ]
// the last two rows (no lateral or vertical speed of the rear axle) only when the
// non-holonomic constraint is enabled, each with its own sigma (lateral_sigma_m_s,
// vertical_sigma_m_s).
//
// Parameter blocks, in order: q_W_I (4, RightQuaternionManifold), v_W_I (3), b_g (3),
// q_I_V (4, RightQuaternionManifold), p_I_V (3), then either r_l (1), r_r (1) or one shared
// r (1) (WheelFactorOptions::shared_radius), then the track width b (1).
// The state is the keyframe's at the measurement instant; a sample between keyframes uses a
// keyframe propagated with sensors::ImuPreintegration::Predict().

#include <ceres/ceres.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <optional>

#include "autocal/geometry/so3.h"
#include "autocal/sensors/sensor_config.h"

namespace autocal {
namespace factors {

struct WheelMeasurement {
  double left_rad_s = 0.0;  // at the instant: the forward-speed row's
  double right_rad_s = 0.0;
  // Raw gyro reading at the wheel sample's instant (IMU frame, bias not removed).
  Eigen::Vector3d gyro_rad_s = Eigen::Vector3d::Zero();
  // The yaw-rate row's left and right rates when gyro_rad_s is a mean over a span: the wheels'
  // mean over the same span (docs/keyframe_factors.md, Eq. K13b). Unset: the instant's.
  std::optional<Eigen::Vector2d> yaw_row_rad_s;

  Eigen::Vector2d YawRowRates() const {
    return yaw_row_rad_s.value_or(Eigen::Vector2d(left_rad_s, right_rad_s));
  }
};

struct WheelFactorOptions {
  double speed_sigma_m_s = 0.02;       // 1-sigma of the wheel forward speed
  double yaw_rate_sigma_rad_s = 0.01;  // 1-sigma of the wheel yaw rate
  bool non_holonomic = true;           // add the zero lateral/vertical speed rows
  // 1-sigma of the rear axle's lateral speed (slip) and vertical speed (the body pitching on
  // its suspension) in V, the non-holonomic rows.
  double lateral_sigma_m_s = 0.05;
  double vertical_sigma_m_s = 0.05;
  bool shared_radius = false;  // one radius block for both wheels
  // When positive, the yaw-rate row's sigma follows the track (Deming, Eq. F22b): with b the
  // factor's track (b, or b_eff for the controller's twist) and b0 this value, the track at
  // which yaw_rate_sigma_rad_s holds, the wheels' part of it scales as b0 / b and the gyro's
  // part (yaw_rate_gyro_sigma_rad_s, included in yaw_rate_sigma_rad_s) stays. With both sides
  // noisy, a fixed sigma would let the wheels' noise attenuate 1 / b and lengthen the track
  // (errors in variables). 0: the sigma is fixed.
  double yaw_row_track_m = 0.0;
  double yaw_rate_gyro_sigma_rad_s = 0.0;
  // The axis, in I (unit), about which the yaw-rate row reads the body rate: the axis the
  // vehicle turns about, measured from the log (docs/keyframe_factors.md, Eq. K13c), so that
  // the row does not depend on the mount's tilt. Zero: V's up axis through q_I_V (w_V.z).
  // The factors refuse a non-finite axis or one whose norm is off 1 by more than 1e-6: the
  // row reads the rate about the axis as given, so its length would scale the row.
  Eigen::Vector3d yaw_axis_I = Eigen::Vector3d::Zero();

  // Sigmas of speed and yaw rate from the encoders' rate noise (Eq. F23) at nominal
  // radius and track width; the other fields keep their defaults.
  static WheelFactorOptions FromEncoderNoise(const sensors::WheelConfig& config, double radius_m,
                                             double track_width_m);
  // The same for wheel speeds with noise s = config.noise_m_s on each wheel (Eq. F25):
  // s / sqrt(2) on the speed, sqrt(2) s / b on the yaw rate.
  static WheelFactorOptions FromWheelSpeedNoise(const sensors::WheelConfig& config,
                                                double track_width_m);
  // The controller's twist: config.noise_m_s on the speed, config.yaw_rate_noise_rad_s on the
  // yaw rate (Eq. F26).
  static WheelFactorOptions FromOdometryNoise(const sensors::WheelConfig& config);
};

class WheelFactor final : public ceres::CostFunction {
 public:
  // Throws autocal::Error on non-finite rates, non-positive sigmas or a yaw axis that is not
  // zero or unit.
  WheelFactor(const WheelMeasurement& measurement, const WheelFactorOptions& options);
  static ceres::CostFunction* Create(const WheelMeasurement& measurement,
                                     const WheelFactorOptions& options) {
    return new WheelFactor(measurement, options);
  }

  // Returns false (an invalid step for Ceres) for a non-positive track width.
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

 private:
  WheelMeasurement m_;
  WheelFactorOptions options_;
};

// Eq. F21: the forward speed v_V and yaw rate w_V of the rear-axle centre V that the state
// predicts, with w_I = gyro - b_g the bias-corrected body rate at the measurement instant.
template <typename T>
struct VehicleMotion {
  geometry::Vector3<T> v_V;
  geometry::Vector3<T> w_V;
  geometry::Vector3<T> w_I;  // the body rate they come from, in I
};

// The same from the IMU's attitude, velocity and bias-corrected body rate w_I.
template <typename T>
VehicleMotion<T> PredictVehicleMotion(const Eigen::Quaternion<T>& q_W_I,
                                      const geometry::Vector3<T>& v_W_I,
                                      const geometry::Vector3<T>& w_I, const T* q_I_V_ptr,
                                      const T* p_I_V_ptr) {
  using Vec3 = geometry::Vector3<T>;
  const Eigen::Map<const Eigen::Quaternion<T>> q_I_V(q_I_V_ptr);
  const Eigen::Map<const Vec3> p_I_V(p_I_V_ptr);
  return {q_I_V.conjugate() * Vec3(q_W_I.conjugate() * v_W_I + w_I.cross(p_I_V)),
          q_I_V.conjugate() * w_I, w_I};
}

template <typename T>
VehicleMotion<T> PredictVehicleMotion(const T* q_W_I_ptr, const T* v_W_I_ptr, const T* b_g_ptr,
                                      const T* q_I_V_ptr, const T* p_I_V_ptr,
                                      const Eigen::Vector3d& gyro_rad_s) {
  using Vec3 = geometry::Vector3<T>;
  const Eigen::Map<const Vec3> b_g(b_g_ptr);
  return PredictVehicleMotion(Eigen::Quaternion<T>(q_W_I_ptr), Vec3(v_W_I_ptr),
                              Vec3(gyro_rad_s.cast<T>() - b_g), q_I_V_ptr, p_I_V_ptr);
}

// The yaw-rate row's sigma at track b (Eq. F22b at fixed radii): sqrt(s_w^2 (b0 / b)^2 + s_g^2)
// with s_w^2 = yaw_rate_sigma^2 - s_g^2 the wheels' part at b0 = yaw_row_track_m; fixed without
// b0. The sliding window's wheel rows evaluate the same weight at the current radii.
template <typename T>
T YawRowSigma(const WheelFactorOptions& options, const T& track) {
  if (!(options.yaw_row_track_m > 0.0)) return T(options.yaw_rate_sigma_rad_s);
  const double s_g2 = options.yaw_rate_gyro_sigma_rad_s * options.yaw_rate_gyro_sigma_rad_s;
  const double s_w2 = options.yaw_rate_sigma_rad_s * options.yaw_rate_sigma_rad_s - s_g2;
  const T ratio = T(options.yaw_row_track_m) / track;
  return sqrt(T(s_w2) * ratio * ratio + T(s_g2));
}

// The rear axle's speed and yaw rate as a wheel form reports them.
template <typename T>
struct AxleMotion {
  T speed;
  T yaw_rate;
};

// From the left and right rear wheels' speeds (m/s) over the track b (Eq. F20, F25):
// (v_l + v_r) / 2 and (v_r - v_l) / b.
template <typename T>
AxleMotion<T> AxleFromWheels(const T& left, const T& right, const T& track) {
  return {T(0.5) * (left + right), (right - left) / track};
}

// From the controller's twist (Eq. F26): k_v v_odo and k_v w_odo b_ctrl / b_eff.
template <typename T>
AxleMotion<T> AxleFromTwist(const T& speed_scale, double speed_m_s, double yaw_rate_rad_s,
                            double controller_track_m, const T& effective_track) {
  return {speed_scale * T(speed_m_s),
          speed_scale * T(yaw_rate_rad_s * controller_track_m) / effective_track};
}

// The yaw rate the yaw-rate row reads from the motion's body rate: about options.yaw_axis_I
// when set (Eq. K13c), else about V's up axis (w_V.z).
template <typename T>
T ReadYawRate(const WheelFactorOptions& options, const VehicleMotion<T>& motion) {
  if (options.yaw_axis_I.isZero(0.0)) return motion.w_V.z();
  return options.yaw_axis_I.cast<T>().dot(motion.w_I);
}

// Eq. F22 for any form: the state's speed and yaw rate (ReadYawRate) minus the wheels'
// (`speed`, `yaw_rate` through the factor's `track`), then the non-holonomic rows when enabled;
// whitened by the options' sigmas, the yaw-rate row's at `track` (YawRowSigma).
template <typename T>
void WheelRows(const VehicleMotion<T>& motion, const T& speed, const T& yaw_rate, const T& track,
               const WheelFactorOptions& options, T* residual) {
  residual[0] = (motion.v_V.x() - speed) / T(options.speed_sigma_m_s);
  residual[1] = (ReadYawRate(options, motion) - yaw_rate) / YawRowSigma(options, track);
  if (options.non_holonomic) {
    residual[2] = motion.v_V.y() / T(options.lateral_sigma_m_s);
    residual[3] = motion.v_V.z() / T(options.vertical_sigma_m_s);
  }
}

// Autodiff twin of WheelFactor with separate radii; the test oracle. The number of residuals
// is 4 with the non-holonomic rows, else 2. It checks nothing but the track, as WheelFactor
// does when it evaluates: a non-positive track width is an invalid step (false).
class WheelResidual {
 public:
  WheelResidual(const WheelMeasurement& measurement, const WheelFactorOptions& options)
      : m_(measurement), options_(options) {}

  static ceres::CostFunction* CreateAutoDiff(const WheelMeasurement& measurement,
                                             const WheelFactorOptions& options) {
    return new ceres::AutoDiffCostFunction<WheelResidual, ceres::DYNAMIC, 4, 3, 3, 4, 3, 1, 1, 1>(
        new WheelResidual(measurement, options), options.non_holonomic ? 4 : 2);
  }

  template <typename T>
  bool operator()(const T* q_W_I, const T* v_W_I, const T* b_g, const T* q_I_V, const T* p_I_V,
                  const T* r_l, const T* r_r, const T* track_width, T* residual) const {
    if (!(track_width[0] > T(0.0))) return false;
    const VehicleMotion<T> motion =
        PredictVehicleMotion(q_W_I, v_W_I, b_g, q_I_V, p_I_V, m_.gyro_rad_s);
    const Eigen::Vector2d yaw_row = m_.YawRowRates();
    const T speed =
        AxleFromWheels(T(m_.left_rad_s) * r_l[0], T(m_.right_rad_s) * r_r[0], track_width[0]).speed;
    const T yaw_rate =
        AxleFromWheels(T(yaw_row(0)) * r_l[0], T(yaw_row(1)) * r_r[0], track_width[0]).yaw_rate;
    WheelRows(motion, speed, yaw_rate, track_width[0], options_, residual);
    return true;
  }

 private:
  WheelMeasurement m_;
  WheelFactorOptions options_;
};

// ---- Wheels as linear speeds (CAN wheel speeds), Eq. F25 ----

struct WheelSpeedMeasurement {
  double left_m_s = 0.0;                                 // rear left, as reported
  double right_m_s = 0.0;                                // rear right
  Eigen::Vector3d gyro_rad_s = Eigen::Vector3d::Zero();  // raw gyro at the same instant
  // The yaw-rate row's speeds over the gyro's span, as WheelMeasurement::yaw_row_rad_s.
  std::optional<Eigen::Vector2d> yaw_row_m_s;

  Eigen::Vector2d YawRowSpeeds() const {
    return yaw_row_m_s.value_or(Eigen::Vector2d(left_m_s, right_m_s));
  }
};

// The reported rear-wheel speeds v_l, v_r scaled by s_l, s_r give the rear axle's motion:
//   v_wheel = (s_l v_l + s_r v_r) / 2,   yaw_wheel = (s_r v_r - s_l v_l) / b.
// Parameter blocks: q_W_I (4), v_W_I (3), b_g (3), q_I_V (4), p_I_V (3), s_l (1), s_r (1),
// track width b (1). Residuals as WheelResidual (4 with the non-holonomic rows, else 2).
class WheelSpeedResidual {
 public:
  WheelSpeedResidual(const WheelSpeedMeasurement& measurement, const WheelFactorOptions& options)
      : m_(measurement), options_(options) {}

  // Throws autocal::Error on non-finite speeds, non-positive sigmas or a yaw axis that is not
  // zero or unit.
  static ceres::CostFunction* Create(const WheelSpeedMeasurement& measurement,
                                     const WheelFactorOptions& options);

  // False (an invalid step) for a non-positive track width.
  template <typename T>
  bool operator()(const T* q_W_I, const T* v_W_I, const T* b_g, const T* q_I_V, const T* p_I_V,
                  const T* scale_left, const T* scale_right, const T* track_width,
                  T* residual) const {
    if (!(track_width[0] > T(0.0))) return false;
    const VehicleMotion<T> motion =
        PredictVehicleMotion(q_W_I, v_W_I, b_g, q_I_V, p_I_V, m_.gyro_rad_s);
    const Eigen::Vector2d yaw_row = m_.YawRowSpeeds();
    const T speed = AxleFromWheels(T(m_.left_m_s) * scale_left[0], T(m_.right_m_s) * scale_right[0],
                                   track_width[0])
                        .speed;
    const T yaw_rate = AxleFromWheels(T(yaw_row(0)) * scale_left[0], T(yaw_row(1)) * scale_right[0],
                                      track_width[0])
                           .yaw_rate;
    WheelRows(motion, speed, yaw_rate, track_width[0], options_, residual);
    return true;
  }

 private:
  WheelSpeedMeasurement m_;
  WheelFactorOptions options_;
};

// ---- Wheels as the controller's speed and yaw rate (odometry twist), Eq. F26 ----

struct OdometryMeasurement {
  double speed_m_s = 0.0;       // v_odo, as reported
  double yaw_rate_rad_s = 0.0;  // w_odo, as reported
  // b_ctrl: the wheel separation the controller divided by (WheelConfig::controller_track_m).
  double controller_track_m = 1.0;
  Eigen::Vector3d gyro_rad_s = Eigen::Vector3d::Zero();  // raw gyro at the same instant
};

// The controller computed v_odo = r0 (w_l + w_r) / 2 and w_odo = r0 (w_r - w_l) / b_ctrl with
// its nominal radius r0. With the true radius r = k_v r0 and the slip of a skid-steer turn
// folded into an effective track b_eff:
//   v_wheel = k_v v_odo,   yaw_wheel = k_v w_odo b_ctrl / b_eff.
// Parameter blocks: q_W_I (4), v_W_I (3), b_g (3), q_I_V (4), p_I_V (3), k_v (1), b_eff (1).
// Residuals as WheelResidual.
class OdometryTwistResidual {
 public:
  OdometryTwistResidual(const OdometryMeasurement& measurement, const WheelFactorOptions& options)
      : m_(measurement), options_(options) {}

  // Throws autocal::Error on a non-finite measurement, a non-positive b_ctrl or sigma, or a yaw
  // axis that is not zero or unit.
  static ceres::CostFunction* Create(const OdometryMeasurement& measurement,
                                     const WheelFactorOptions& options);

  // False (an invalid step) for a non-positive effective track.
  template <typename T>
  bool operator()(const T* q_W_I, const T* v_W_I, const T* b_g, const T* q_I_V, const T* p_I_V,
                  const T* speed_scale, const T* effective_track, T* residual) const {
    if (!(effective_track[0] > T(0.0))) return false;
    const VehicleMotion<T> motion =
        PredictVehicleMotion(q_W_I, v_W_I, b_g, q_I_V, p_I_V, m_.gyro_rad_s);
    const AxleMotion<T> axle = AxleFromTwist(speed_scale[0], m_.speed_m_s, m_.yaw_rate_rad_s,
                                             m_.controller_track_m, effective_track[0]);
    WheelRows(motion, axle.speed, axle.yaw_rate, effective_track[0], options_, residual);
    return true;
  }

 private:
  OdometryMeasurement m_;
  WheelFactorOptions options_;
};

}  // namespace factors
}  // namespace autocal
