#pragma once

// Rear-wheel encoder factor (docs/factors.md, "Wheel-encoder factor").
//
// The wheel rates give the forward speed and yaw rate of the rear-axle centre V
// (Eq. F20):  v_wheel = (w_l r_l + w_r r_r) / 2,   yaw_wheel = (w_r r_r - w_l r_l) / b.
// The state predicts them through T_I_V (Eq. F21): with w_I = gyro - b_g the bias-corrected
// body rate at the same instant,
//   v_V = R_I_V^T (R_W_I^T v_W_I + w_I x p_I_V),    w_V = R_I_V^T w_I,
// and the residual is (Eq. F22)
//   r = [ (v_V.x - v_wheel) / s_v,  (w_V.z - yaw_wheel) / s_yaw,  v_V.y / s_nh,  v_V.z / s_nh ]
// the last two rows (no lateral or vertical speed of the rear axle) only when the
// non-holonomic constraint is enabled.
//
// Parameter blocks, in order: q_W_I (4, RightQuaternionManifold), v_W_I (3), b_g (3),
// q_I_V (4, RightQuaternionManifold), p_I_V (3), then either r_l (1), r_r (1) or one shared
// r (1) (WheelFactorOptions::shared_radius), then the track width b (1).
// The state is the keyframe's at the measurement instant; a sample between keyframes uses a
// keyframe propagated with sensors::ImuPreintegration::Predict().

#include <ceres/ceres.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "autocal/geometry/so3.h"
#include "autocal/sensors/sensor_config.h"

namespace autocal {
namespace factors {

struct WheelMeasurement {
  double left_rad_s = 0.0;
  double right_rad_s = 0.0;
  // Raw gyro reading at the wheel sample's instant (IMU frame, bias not removed).
  Eigen::Vector3d gyro_rad_s = Eigen::Vector3d::Zero();
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

  // Sigmas of speed and yaw rate from the encoders' rate noise (Eq. F23) at nominal
  // radius and track width; the other fields keep their defaults.
  static WheelFactorOptions FromEncoderNoise(const sensors::WheelConfig& config, double radius_m,
                                             double track_width_m);
};

class WheelFactor final : public ceres::CostFunction {
 public:
  // Throws autocal::Error on non-finite rates or non-positive sigmas.
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

// Autodiff twin of WheelFactor with separate radii; the test oracle. The number of residuals
// is 4 with the non-holonomic rows, else 2.
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
  bool operator()(const T* q_W_I_ptr, const T* v_W_I_ptr, const T* b_g_ptr, const T* q_I_V_ptr,
                  const T* p_I_V_ptr, const T* r_l, const T* r_r, const T* track_width,
                  T* residual) const {
    using Vec3 = geometry::Vector3<T>;
    const Eigen::Map<const Eigen::Quaternion<T>> q_W_I(q_W_I_ptr), q_I_V(q_I_V_ptr);
    const Eigen::Map<const Vec3> v_W_I(v_W_I_ptr), b_g(b_g_ptr), p_I_V(p_I_V_ptr);
    const Vec3 w_I = m_.gyro_rad_s.cast<T>() - b_g;
    const Vec3 v_V = q_I_V.conjugate() * Vec3(q_W_I.conjugate() * v_W_I + w_I.cross(p_I_V));
    const Vec3 w_V = q_I_V.conjugate() * w_I;
    const T left = T(m_.left_rad_s) * r_l[0];
    const T right = T(m_.right_rad_s) * r_r[0];
    residual[0] = (v_V.x() - T(0.5) * (left + right)) / T(options_.speed_sigma_m_s);
    residual[1] = (w_V.z() - (right - left) / track_width[0]) / T(options_.yaw_rate_sigma_rad_s);
    if (options_.non_holonomic) {
      residual[2] = v_V.y() / T(options_.lateral_sigma_m_s);
      residual[3] = v_V.z() / T(options_.vertical_sigma_m_s);
    }
    return true;
  }

 private:
  WheelMeasurement m_;
  WheelFactorOptions options_;
};

}  // namespace factors
}  // namespace autocal
