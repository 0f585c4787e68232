#include "autocal/factors/wheel_factor.h"

#include <cmath>
#include <string>

#include "autocal/common/error.h"
#include "autocal/common/format.h"
#include "autocal/geometry/manifolds.h"
#include "factors/sigma_check.h"

namespace autocal {
namespace factors {

namespace {

void CheckSigma(double sigma, const char* name) {
  internal::CheckSigma(sigma, std::string("wheel factor: ") + name);
}

// How far the yaw axis's length may be from 1: the yaw-rate row reads the rate about it as
// given, so its length scales the row; a normalised axis is unit to rounding.
constexpr double kYawAxisNormTolerance = 1e-6;

void CheckYawAxis(const Eigen::Vector3d& axis) {
  if (axis.isZero(0.0)) return;  // the row reads w_V.z
  if (!axis.allFinite() || !(std::abs(axis.norm() - 1.0) <= kYawAxisNormTolerance)) {
    throw Error("wheel factor: yaw_axis_I must be zero or a finite unit vector (norm within " +
                FormatShort(kYawAxisNormTolerance) + " of 1), got (" + FormatShort(axis.x()) +
                ", " + FormatShort(axis.y()) + ", " + FormatShort(axis.z()) +
                "), norm - 1 = " + FormatShort(axis.norm() - 1.0));
  }
}

// The options' sigmas and yaw axis.
void CheckOptions(const WheelFactorOptions& options) {
  CheckYawAxis(options.yaw_axis_I);
  CheckSigma(options.speed_sigma_m_s, "speed_sigma_m_s");
  CheckSigma(options.yaw_rate_sigma_rad_s, "yaw_rate_sigma_rad_s");
  if (options.yaw_row_track_m != 0.0) {
    CheckSigma(options.yaw_row_track_m, "yaw_row_track_m");
    if (!(options.yaw_rate_gyro_sigma_rad_s >= 0.0) ||
        !(options.yaw_rate_gyro_sigma_rad_s < options.yaw_rate_sigma_rad_s)) {
      throw Error("wheel factor: yaw_rate_gyro_sigma_rad_s must be in [0, yaw_rate_sigma_rad_s)");
    }
  }
  if (options.non_holonomic) {
    CheckSigma(options.lateral_sigma_m_s, "lateral_sigma_m_s");
    CheckSigma(options.vertical_sigma_m_s, "vertical_sigma_m_s");
  }
}

int NumRows(const WheelFactorOptions& options) { return options.non_holonomic ? 4 : 2; }

}  // namespace

WheelFactorOptions WheelFactorOptions::FromWheelSpeedNoise(const sensors::WheelConfig& config,
                                                           double track_width_m) {
  CheckSigma(config.noise_m_s, "wheel speed noise");
  CheckSigma(track_width_m, "track width");
  WheelFactorOptions options;
  // Eq. F25: independent speed noise s on both wheels.
  options.speed_sigma_m_s = config.noise_m_s / std::sqrt(2.0);
  options.yaw_rate_sigma_rad_s = std::sqrt(2.0) * config.noise_m_s / track_width_m;
  return options;
}

WheelFactorOptions WheelFactorOptions::FromOdometryNoise(const sensors::WheelConfig& config) {
  CheckSigma(config.noise_m_s, "odometry speed noise");
  CheckSigma(config.yaw_rate_noise_rad_s, "odometry yaw rate noise");
  WheelFactorOptions options;
  options.speed_sigma_m_s = config.noise_m_s;
  options.yaw_rate_sigma_rad_s = config.yaw_rate_noise_rad_s;
  return options;
}

ceres::CostFunction* WheelSpeedResidual::Create(const WheelSpeedMeasurement& measurement,
                                                const WheelFactorOptions& options) {
  if (!std::isfinite(measurement.left_m_s) || !std::isfinite(measurement.right_m_s) ||
      !measurement.YawRowSpeeds().allFinite() || !measurement.gyro_rad_s.allFinite()) {
    throw Error("wheel-speed factor: wheel speed or gyro rate is not finite");
  }
  CheckOptions(options);
  return new ceres::AutoDiffCostFunction<WheelSpeedResidual, ceres::DYNAMIC, 4, 3, 3, 4, 3, 1, 1,
                                         1>(new WheelSpeedResidual(measurement, options),
                                            NumRows(options));
}

ceres::CostFunction* OdometryTwistResidual::Create(const OdometryMeasurement& measurement,
                                                   const WheelFactorOptions& options) {
  if (!std::isfinite(measurement.speed_m_s) || !std::isfinite(measurement.yaw_rate_rad_s) ||
      !measurement.gyro_rad_s.allFinite()) {
    throw Error("odometry factor: speed, yaw rate or gyro rate is not finite");
  }
  CheckSigma(measurement.controller_track_m, "controller track (b_ctrl)");
  CheckOptions(options);
  return new ceres::AutoDiffCostFunction<OdometryTwistResidual, ceres::DYNAMIC, 4, 3, 3, 4, 3, 1,
                                         1>(new OdometryTwistResidual(measurement, options),
                                            NumRows(options));
}

WheelFactorOptions WheelFactorOptions::FromEncoderNoise(const sensors::WheelConfig& config,
                                                        double radius_m, double track_width_m) {
  CheckSigma(config.noise_rad_s, "encoder rate noise");
  CheckSigma(radius_m, "wheel radius");
  CheckSigma(track_width_m, "track width");
  WheelFactorOptions options;
  // Eq. F23: independent rate noise s_w on both wheels.
  options.speed_sigma_m_s = radius_m * config.noise_rad_s / std::sqrt(2.0);
  options.yaw_rate_sigma_rad_s = std::sqrt(2.0) * radius_m * config.noise_rad_s / track_width_m;
  return options;
}

WheelFactor::WheelFactor(const WheelMeasurement& measurement, const WheelFactorOptions& options)
    : m_(measurement), options_(options) {
  if (!std::isfinite(measurement.left_rad_s) || !std::isfinite(measurement.right_rad_s) ||
      !measurement.YawRowRates().allFinite() || !measurement.gyro_rad_s.allFinite()) {
    throw Error("wheel factor: wheel or gyro rate is not finite");
  }
  CheckOptions(options);
  set_num_residuals(NumRows(options));
  auto* sizes = mutable_parameter_block_sizes();
  *sizes = {4, 3, 3, 4, 3, 1};
  if (!options.shared_radius) sizes->push_back(1);
  sizes->push_back(1);
}

bool WheelFactor::Evaluate(double const* const* parameters, double* residuals,
                           double** jacobians) const {
  const Eigen::Map<const Eigen::Quaterniond> q_W_I(parameters[0]);
  const Eigen::Map<const Eigen::Vector3d> v_W_I(parameters[1]);
  const Eigen::Map<const Eigen::Vector3d> b_g(parameters[2]);
  const Eigen::Map<const Eigen::Quaterniond> q_I_V(parameters[3]);
  const Eigen::Map<const Eigen::Vector3d> p_I_V(parameters[4]);
  const int radius_right_index = options_.shared_radius ? 5 : 6;
  const int track_index = radius_right_index + 1;
  const double r_l = parameters[5][0];
  const double r_r = parameters[radius_right_index][0];
  const double b = parameters[track_index][0];
  if (!(b > 0.0)) return false;

  // Eq. F20-F22.
  const Eigen::Matrix3d Rt_I_V = q_I_V.conjugate().toRotationMatrix();
  const Eigen::Vector3d w_I = m_.gyro_rad_s - b_g;
  const Eigen::Vector3d v_I = q_W_I.conjugate() * v_W_I;
  const Eigen::Vector3d v_V = Rt_I_V * (v_I + w_I.cross(p_I_V));
  const Eigen::Vector3d w_V = Rt_I_V * w_I;
  const double left = m_.left_rad_s * r_l;
  const double right = m_.right_rad_s * r_r;
  const Eigen::Vector2d yaw_row = m_.YawRowRates();  // Eq. K13b
  const double yaw_wheel = (yaw_row(1) * r_r - yaw_row(0) * r_l) / b;
  const double inv_s_v = 1.0 / options_.speed_sigma_m_s;
  const double s_yaw = YawRowSigma(options_, b);  // Eq. F22b
  const double inv_s_yaw = 1.0 / s_yaw;
  const double inv_s_lat = options_.non_holonomic ? 1.0 / options_.lateral_sigma_m_s : 0.0;
  const double inv_s_vert = options_.non_holonomic ? 1.0 / options_.vertical_sigma_m_s : 0.0;
  residuals[0] = (v_V.x() - 0.5 * (left + right)) * inv_s_v;
  const bool yaw_axis = !options_.yaw_axis_I.isZero(0.0);  // Eq. K13c
  residuals[1] = ((yaw_axis ? options_.yaw_axis_I.dot(w_I) : w_V.z()) - yaw_wheel) * inv_s_yaw;
  if (options_.non_holonomic) {
    residuals[2] = v_V.y() * inv_s_lat;
    residuals[3] = v_V.z() * inv_s_vert;
  }
  if (jacobians == nullptr) return true;

  // Eq. F24: rows [v_V.x, w_V.z, v_V.y, v_V.z] scaled by their sigmas, each written straight
  // into Ceres' row-major block (lifted to the quaternion's ambient coordinates when q is
  // given) from the transposed rows of d v_V and d w_V.z. Row i of Rt_I_V Hat(a) is
  // (c_i x a)^T with c_i the i-th column of R_I_V. The blocks are tiny: generic products,
  // temporaries and loops over the row count cost more than the arithmetic.
  const bool non_holonomic = options_.non_holonomic;
  auto store_row = [](const Eigen::Vector3d& row, const double* q, double* out) {
    if (q != nullptr) {
      geometry::LiftTangentRow(row.transpose(), q, out);
    } else {
      out[0] = row.x();
      out[1] = row.y();
      out[2] = row.z();
    }
  };
  auto store = [&](const Eigen::Vector3d& d_v_x, const Eigen::Vector3d& d_w_z,
                   const Eigen::Vector3d& d_v_y, const Eigen::Vector3d& d_v_z, const double* q,
                   double* out) {
    const int stride = q != nullptr ? 4 : 3;
    store_row(inv_s_v * d_v_x, q, out);
    store_row(inv_s_yaw * d_w_z, q, out + stride);
    if (non_holonomic) {
      store_row(inv_s_lat * d_v_y, q, out + 2 * stride);
      store_row(inv_s_vert * d_v_z, q, out + 3 * stride);
    }
  };
  const Eigen::Matrix3d R_I_V = Rt_I_V.transpose();
  const Eigen::Vector3d zero = Eigen::Vector3d::Zero();
  auto store_rotated_hat = [&](const Eigen::Vector3d& a, const Eigen::Vector3d& d_w_z,
                               const double* q, double* out) {
    store(R_I_V.col(0).cross(a), d_w_z, R_I_V.col(1).cross(a), R_I_V.col(2).cross(a), q, out);
  };
  if (jacobians[0] != nullptr) store_rotated_hat(v_I, zero, parameters[0], jacobians[0]);
  if (jacobians[1] != nullptr) {
    const Eigen::Matrix3d R_W_V = (q_W_I * q_I_V).toRotationMatrix();
    store(R_W_V.col(0), zero, R_W_V.col(1), R_W_V.col(2), nullptr, jacobians[1]);
  }
  if (jacobians[2] != nullptr) {
    store_rotated_hat(p_I_V, yaw_axis ? Eigen::Vector3d(-options_.yaw_axis_I) : -R_I_V.col(2),
                      nullptr, jacobians[2]);
  }
  if (jacobians[3] != nullptr) {
    // d v_V / d(right tangent of q_I_V) = Hat(v_V), d w_V / d(...) = Hat(w_V).
    store(Eigen::Vector3d(0.0, -v_V.z(), v_V.y()),
          yaw_axis ? zero : Eigen::Vector3d(-w_V.y(), w_V.x(), 0.0),
          Eigen::Vector3d(v_V.z(), 0.0, -v_V.x()), Eigen::Vector3d(-v_V.y(), v_V.x(), 0.0),
          parameters[3], jacobians[3]);
  }
  if (jacobians[4] != nullptr) store_rotated_hat(w_I, zero, nullptr, jacobians[4]);
  // Scalar blocks: d r / d(r_l, r_r, b) of the wheel-side prediction.
  const Eigen::Vector4d d_r_l(-0.5 * m_.left_rad_s * inv_s_v, yaw_row(0) / b * inv_s_yaw, 0, 0);
  const Eigen::Vector4d d_r_r(-0.5 * m_.right_rad_s * inv_s_v, -yaw_row(1) / b * inv_s_yaw, 0, 0);
  // Fixed-size writes: a loop over the row count compiles to a call to memcpy.
  auto store_scalar = [non_holonomic](const Eigen::Vector4d& column, double* out) {
    if (out == nullptr) return;
    out[0] = column(0);
    out[1] = column(1);
    if (non_holonomic) {
      out[2] = column(2);
      out[3] = column(3);
    }
  };
  if (options_.shared_radius) {
    store_scalar(d_r_l + d_r_r, jacobians[5]);
  } else {
    store_scalar(d_r_l, jacobians[5]);
    store_scalar(d_r_r, jacobians[6]);
  }
  // d/db of (w_V.z - yaw_wheel) / s(b): yaw_wheel / (b s) - r s'(b) / s, with
  // s'(b) = -(s^2 - s_g^2) / (b s) when the sigma follows the track (Eq. F22b).
  double d_yaw_d_b = yaw_wheel / b * inv_s_yaw;
  if (options_.yaw_row_track_m > 0.0) {
    const double s_g = options_.yaw_rate_gyro_sigma_rad_s;
    const double d_s_d_b = -(s_yaw * s_yaw - s_g * s_g) / (b * s_yaw);
    d_yaw_d_b -= residuals[1] * d_s_d_b * inv_s_yaw;
  }
  store_scalar(Eigen::Vector4d(0.0, d_yaw_d_b, 0.0, 0.0), jacobians[track_index]);
  return true;
}

}  // namespace factors
}  // namespace autocal
