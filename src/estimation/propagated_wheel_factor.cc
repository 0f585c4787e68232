// The sliding window's wheel rows with analytic Jacobians (PropagatedWheelFactor, declared in
// sliding_window_factors.h; derivation there and in docs/sliding_window.md, "Wheel rows with
// analytic Jacobians").

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <utility>

#include "autocal/common/error.h"
#include "autocal/geometry/manifolds.h"
#include "autocal/geometry/so3.h"
#include "estimation/sliding_window_factors.h"

namespace autocal {
namespace estimation {
namespace internal {

namespace {

// The wheel factor's blocks: q_W_I, v_W_I, b_g, q_I_V, p_I_V, r_l, r_r, track width.
constexpr int kWheelBlocks = 8;
constexpr int kWheelBlockSizes[kWheelBlocks] = {4, 3, 3, 4, 3, 1, 1, 1};
constexpr int kMaxRows = 4;

using RowMajor3 = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor, kMaxRows, 3>;

}  // namespace

PropagatedWheelFactor::PropagatedWheelFactor(sensors::ImuPreintegration pim,
                                             const factors::WheelMeasurement& measurement,
                                             const factors::WheelFactorOptions& options,
                                             double encoder_sigma_rad_s, double gyro_sigma_rad_s,
                                             double speed_variance_m2_s2)
    : pim_(std::move(pim)),
      wheel_(measurement, options),
      speed_sigma_m_s_(options.speed_sigma_m_s),
      yaw_rate_sigma_rad_s_(options.yaw_rate_sigma_rad_s),
      encoder_sigma_rad_s_(encoder_sigma_rad_s),
      gyro_sigma_rad_s_(gyro_sigma_rad_s),
      speed_variance_m2_s2_(speed_variance_m2_s2) {
  if (options.shared_radius) {
    throw Error("PropagatedWheelFactor: the window estimates both wheel radii (no shared radius)");
  }
  if (!(encoder_sigma_rad_s > 0.0) || !(gyro_sigma_rad_s > 0.0) ||
      !std::isfinite(encoder_sigma_rad_s) || !std::isfinite(gyro_sigma_rad_s)) {
    throw Error("PropagatedWheelFactor: the encoder and gyro sigmas must be positive and finite");
  }
  if (!(speed_variance_m2_s2 >= 0.0) || !std::isfinite(speed_variance_m2_s2)) {
    throw Error("PropagatedWheelFactor: the speed row's added variance must be finite and >= 0");
  }
  set_num_residuals(wheel_.num_residuals());
  *mutable_parameter_block_sizes() = {4, 3, 3, 3, 4, 3, 1, 1, 1};
}

bool PropagatedWheelFactor::Evaluate(double const* const* parameters, double* residuals,
                                     double** jacobians) const {
  const Eigen::Map<const Eigen::Quaterniond> q_k(parameters[0]);
  const Eigen::Map<const Eigen::Vector3d> v_k(parameters[1]);
  const Eigen::Vector3d b_g(parameters[2]);
  const Eigen::Vector3d b_a(parameters[3]);
  const double r_l = parameters[6][0], r_r = parameters[7][0], b = parameters[8][0];

  // The propagated attitude and body velocity.
  const sensors::LinearizedDeltas deltas = pim_.Linearized();
  Eigen::Quaterniond dq;
  Eigen::Vector3d dv, phi_bg;
  deltas.Corrected<double>(b_g, b_a, &dq, &dv, nullptr, &phi_bg);
  const Eigen::Vector3d w = q_k.conjugate() * (v_k + pim_.gravity_W() * pim_.dt_s());
  const Eigen::Vector3d u = w + dv;
  const double* wheel_parameters[kWheelBlocks] = {dq.coeffs().data(), u.data(),      parameters[2],
                                                  parameters[4],      parameters[5], parameters[6],
                                                  parameters[7],      parameters[8]};
  const int rows = num_residuals();

  // Rows 0 and 1 whitened at the current radii and track width ("Wheel rows").
  const double s_w = encoder_sigma_rad_s_, s_g = gyro_sigma_rad_s_;
  const double radius_sq = r_l * r_l + r_r * r_r;
  const double speed_variance = 0.25 * s_w * s_w * radius_sq + speed_variance_m2_s2_;
  const double speed_scale = speed_sigma_m_s_ / std::sqrt(speed_variance);
  const double yaw_variance = s_w * s_w * radius_sq + b * b * s_g * s_g;
  const double yaw_scale = yaw_rate_sigma_rad_s_ * b / std::sqrt(yaw_variance);

  if (jacobians == nullptr) {
    if (!wheel_.Evaluate(wheel_parameters, residuals, nullptr)) return false;
    residuals[0] *= speed_scale;
    residuals[1] *= yaw_scale;
    return true;
  }

  // The wheel factor's Jacobians, row-major rows x size per block.
  double wheel_storage[kWheelBlocks][kMaxRows * 4];
  double* wheel_jacobians[kWheelBlocks];
  for (int i = 0; i < kWheelBlocks; ++i) wheel_jacobians[i] = wheel_storage[i];
  if (!wheel_.Evaluate(wheel_parameters, residuals, wheel_jacobians)) return false;
  const double e0 = residuals[0], e1 = residuals[1];  // before the scales
  residuals[0] *= speed_scale;
  residuals[1] *= yaw_scale;
  const auto wheel_block = [&](int i, int size) {
    return Eigen::Map<
        const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor, kMaxRows, 4>>(
        wheel_storage[i], rows, size);
  };
  // The attitude's rows in its right tangent: the wheel factor gives them lifted to dq's
  // ambient coordinates, which dq's PlusJacobian takes back exactly.
  Eigen::Matrix<double, 4, 3, Eigen::RowMajor> dq_plus;
  geometry::RightQuaternionManifold().PlusJacobian(dq.coeffs().data(), dq_plus.data());
  const RowMajor3 J_dq = wheel_block(0, 4) * dq_plus;
  const RowMajor3 J_u = wheel_block(1, 3);

  // Each output block, before the scales: rows x size, row-major.
  const auto scale_rows = [&](double* block, int size) {
    for (int c = 0; c < size; ++c) {
      block[c] *= speed_scale;
      block[size + c] *= yaw_scale;
    }
  };
  const auto output = [&](int index, int size) {
    return Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
        jacobians[index], rows, size);
  };
  if (jacobians[0] != nullptr) {
    // u = Exp(theta)^T R_k^T (v_k + g dt) + dv: du/dtheta = Hat(w).
    const RowMajor3 tangent = J_u * geometry::Hat(w);
    for (int r = 0; r < rows; ++r) {
      geometry::LiftTangentRow(tangent.row(r), parameters[0], jacobians[0] + 4 * r);
    }
    scale_rows(jacobians[0], 4);
  }
  if (jacobians[1] != nullptr) {
    output(1, 3) = J_u * q_k.conjugate().toRotationMatrix();
    scale_rows(jacobians[1], 3);
  }
  if (jacobians[2] != nullptr) {
    // dR = dR_0 Exp(phi_bg), phi_bg = d_R_d_bg (b_g - b_g0): its right tangent moves by
    // Jr(phi_bg) d_R_d_bg db_g.
    output(2, 3) = wheel_block(2, 3) + J_dq * geometry::RightJacobian(phi_bg) * deltas.d_R_d_bg +
                   J_u * deltas.d_v_d_bg;
    scale_rows(jacobians[2], 3);
  }
  if (jacobians[3] != nullptr) {
    output(3, 3) = J_u * deltas.d_v_d_ba;
    scale_rows(jacobians[3], 3);
  }
  for (int i = 4; i < 9; ++i) {  // q_I_V, p_I_V, r_l, r_r, b: the wheel factor's own
    if (jacobians[i] == nullptr) continue;
    const int size = kWheelBlockSizes[i - 1];
    output(i, size) = wheel_block(i - 1, size);
    scale_rows(jacobians[i], size);
  }
  // The scales' derivatives: d speed_scale / dr = -speed_scale s_w^2 r / (4 speed_variance),
  // d yaw_scale / dr = -yaw_scale s_w^2 r / yaw_variance and
  // d yaw_scale / db = yaw_scale (1 / b - b s_g^2 / yaw_variance).
  if (jacobians[6] != nullptr) {
    jacobians[6][0] -= e0 * speed_scale * 0.25 * s_w * s_w * r_l / speed_variance;
    jacobians[6][1] -= e1 * yaw_scale * s_w * s_w * r_l / yaw_variance;
  }
  if (jacobians[7] != nullptr) {
    jacobians[7][0] -= e0 * speed_scale * 0.25 * s_w * s_w * r_r / speed_variance;
    jacobians[7][1] -= e1 * yaw_scale * s_w * s_w * r_r / yaw_variance;
  }
  if (jacobians[8] != nullptr) {
    jacobians[8][1] += e1 * yaw_scale * (1.0 / b - b * s_g * s_g / yaw_variance);
  }
  return true;
}

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
