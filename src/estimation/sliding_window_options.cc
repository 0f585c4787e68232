// Validation of SlidingWindowOptions (one clear message naming the first invalid option), and
// the initial sigmas in the state prior's order.
#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <string>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/units.h"
#include "autocal/estimation/sliding_window_blocks.h"
#include "estimation/sliding_window_internal.h"

namespace autocal {
namespace estimation {

Eigen::Matrix<double, 15, 1> SlidingWindowInitialStateSigmas::InStatePriorOrder() const {
  Eigen::Matrix<double, 15, 1> sigmas;
  sigmas << Eigen::Vector3d::Constant(rotation_deg * kDegToRad),
      Eigen::Vector3d::Constant(position_m), Eigen::Vector3d::Constant(velocity_m_s),
      Eigen::Vector3d::Constant(gyro_bias_rad_s), Eigen::Vector3d::Constant(accel_bias_m_s2);
  return sigmas;
}
namespace internal {
namespace {

void CheckPositive(double value, const char* name) {
  if (!(value > 0.0) || !std::isfinite(value)) {
    throw Error(std::string("SlidingWindowOptions: ") + name + " must be positive and finite");
  }
}

void CheckNonNegative(double value, const char* name) {
  if (!(value >= 0.0) || !std::isfinite(value)) {
    throw Error(std::string("SlidingWindowOptions: ") + name + " must be non-negative and finite");
  }
}

void CheckPairing(const PairingOptions& p, const WindowPairingOptions& w) {
  if (p.max_residuals_per_sweep < 0) {
    throw Error("SlidingWindowOptions: pairing.max_residuals_per_sweep must not be negative");
  }
  if (w.max_plane_misses < 0 || w.max_plane_misses > 255) {
    throw Error("SlidingWindowOptions: window_pairing.max_plane_misses must be in [0, 255], got " +
                std::to_string(w.max_plane_misses));
  }
  CheckPositive(p.residual_voxel_m, "pairing.residual_voxel_m");
  CheckNonNegative(p.residual_max_range_m, "pairing.residual_max_range_m");
  CheckPositive(p.map_voxel_m, "pairing.map_voxel_m");
  CheckPositive(p.point_sigma_m, "pairing.point_sigma_m");
  CheckPositive(p.max_point_to_plane_m, "pairing.max_point_to_plane_m");
  CheckNonNegative(w.gate_extrinsic_factor, "window_pairing.gate_extrinsic_factor");
  CheckNonNegative(w.gate_extrinsic_free_deg, "window_pairing.gate_extrinsic_free_deg");
  CheckNonNegative(w.settled_extrinsic_deg, "window_pairing.settled_extrinsic_deg");
  CheckNonNegative(w.reassociation_tolerance_m, "window_pairing.reassociation_tolerance_m");
  CheckNonNegative(w.map_rebuild_tolerance_m, "window_pairing.map_rebuild_tolerance_m");
  if (p.partner_offsets.empty() ||
      std::count(p.partner_offsets.begin(), p.partner_offsets.end(), 0) > 0) {
    throw Error("SlidingWindowOptions: pairing.partner_offsets must be non-empty and non-zero");
  }
  std::vector<int> offsets = p.partner_offsets;
  std::sort(offsets.begin(), offsets.end());
  if (std::adjacent_find(offsets.begin(), offsets.end()) != offsets.end()) {
    throw Error("SlidingWindowOptions: pairing.partner_offsets must not repeat an offset");
  }
  if (!p.fallback_partner_offsets.empty()) {
    throw Error(
        "SlidingWindowOptions: pairing.fallback_partner_offsets must be empty (the window walks "
        "partner_offsets only; put near keyframes there)");
  }
  if (w.settled_partner_count < 1) {
    throw Error("SlidingWindowOptions: window_pairing.settled_partner_count must be >= 1");
  }
}

void CheckWheelRows(const WheelRowOptions& w) {
  if (w.max_samples_per_interval < 0) {
    throw Error("SlidingWindowOptions: wheel_rows.max_samples_per_interval must not be negative");
  }
  CheckPositive(w.vertical_sigma_m_s, "wheel_rows.vertical_sigma_m_s");
  CheckNonNegative(w.non_holonomic_correlation_s, "wheel_rows.non_holonomic_correlation_s");
  CheckNonNegative(w.gyro_mean_span_s, "wheel_rows.gyro_mean_span_s");
  CheckNonNegative(w.max_turning_axis_error_deg, "wheel_rows.max_turning_axis_error_deg");
  CheckNonNegative(w.planar_rotation_sigma_rad_s, "wheel_rows.planar_rotation_sigma_rad_s");
}

void CheckPriors(const SlidingWindowCalibrationPrior& c, const SlidingWindowInitialStateSigmas& x) {
  for (double s :
       {c.extrinsic_rotation_deg, c.extrinsic_translation_m, c.time_offset_s, c.wheel_radius_m,
        c.track_width_m, c.vehicle_rotation_deg, c.vehicle_translation_m, c.gnss_lever_arm_m,
        c.wheel_speed_scale, c.odometry_speed_scale, c.effective_track_m}) {
    CheckPositive(s, "calibration_prior sigmas");
  }
  for (const auto& [id, sigmas] : c.axis_sigmas) {
    const sensors::CalibrationBlockInfo& info = sensors::CalibrationBlock(id);
    if (!WindowSupports(id) || info.tangent_size != 3) {
      throw Error(std::string("SlidingWindowOptions: calibration_prior.axis_sigmas holds ") +
                  info.key + ", which is not a three-axis block of the window");
    }
    for (int i = 0; i < 3; ++i) CheckPositive(sigmas(i), "calibration_prior.axis_sigmas");
  }
  if (c.mean) {
    const sensors::Calibration& m = *c.mean;
    const bool finite = m.q_I_L.coeffs().allFinite() && m.p_I_L.allFinite() &&
                        m.q_I_V.coeffs().allFinite() && m.p_I_V.allFinite() &&
                        m.p_I_A.allFinite() && std::isfinite(m.time_offset_lidar_imu_s) &&
                        std::isfinite(m.wheel_radius_left_m) &&
                        std::isfinite(m.wheel_radius_right_m) && std::isfinite(m.track_width_m);
    if (!finite || m.q_I_L.norm() < 0.5 || m.q_I_V.norm() < 0.5) {
      throw Error(
          "SlidingWindowOptions: calibration_prior.mean must be finite with unit quaternions");
    }
  }
  for (double s :
       {x.rotation_deg, x.position_m, x.velocity_m_s, x.gyro_bias_rad_s, x.accel_bias_m_s2}) {
    CheckPositive(s, "initial_state_sigmas");
  }
}

}  // namespace

PairingOptions PairingWithinWindow(const SlidingWindowOptions& o) {
  PairingOptions p = o.pairing;
  p.partner_offsets.erase(
      std::remove_if(p.partner_offsets.begin(), p.partner_offsets.end(),
                     [&](int offset) { return std::abs(offset) > o.window_size; }),
      p.partner_offsets.end());
  return p;
}

void CheckOptions(const SlidingWindowOptions& o) {
  if (o.window_size < 2) throw Error("SlidingWindowOptions: window_size must be at least 2");
  if (o.linearization.passes_per_update < 0) {
    throw Error("SlidingWindowOptions: linearization.passes_per_update must be >= 0");
  }
  CheckNonNegative(o.linearization.relinearization_tolerance_m,
                   "linearization.relinearization_tolerance_m");
  if (o.solver.max_iterations < 1) {
    throw Error("SlidingWindowOptions: solver.max_iterations must be at least 1");
  }
  CheckPositive(o.solver.function_tolerance, "solver.function_tolerance");
  CheckNonNegative(o.solver.gradient_tolerance, "solver.gradient_tolerance");
  CheckNonNegative(o.solver.parameter_tolerance, "solver.parameter_tolerance");
  CheckPositive(o.solver.initial_trust_region_radius, "solver.initial_trust_region_radius");
  CheckPairing(o.pairing, o.window_pairing);
  if (PairingWithinWindow(o).partner_offsets.empty()) {
    throw Error("SlidingWindowOptions: no pairing.partner_offsets lies within the window of " +
                std::to_string(o.window_size) + " keyframes (|offset| <= window_size)");
  }
  CheckWheelRows(o.wheel_rows);
  CheckPositive(o.wheel.noise_rad_s, "wheel.noise_rad_s");
  CheckPositive(o.wheel.lateral_slip_sigma_m_s, "wheel.lateral_slip_sigma_m_s");
  CheckNonNegative(o.wheel.cornering_compliance_rad_per_m_s2,
                   "wheel.cornering_compliance_rad_per_m_s2");
  CheckPositive(o.imu.gravity_m_s2, "imu.gravity_m_s2");
  CheckNonNegative(o.imu_coverage_margin_s, "imu_coverage_margin_s");
  CheckNonNegative(o.min_keyframe_interval_s, "min_keyframe_interval_s");
  CheckPriors(o.calibration_prior, o.initial_state_sigmas);
  o.gnss_std_scale.Check("SlidingWindowOptions: gnss_std_scale");
  for (const sensors::CalibrationBlockId id : o.tested_fixed_blocks) {
    if (!WindowSupports(id) || Estimated(id, o.estimate)) {
      throw Error(std::string("SlidingWindowOptions: tested_fixed_blocks names ") +
                  sensors::CalibrationBlock(id).name +
                  ", which the window does not hold fixed (it estimates it or has no setting "
                  "for it)");
    }
  }
  if (o.initial_state_covariance) {
    const Eigen::Matrix<double, 15, 15>& c = *o.initial_state_covariance;
    if (!c.allFinite() || !c.isApprox(c.transpose(), 1e-9) || c.llt().info() != Eigen::Success) {
      throw Error(
          "SlidingWindowOptions: initial_state_covariance must be finite, symmetric and "
          "positive definite");
    }
  }
}

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
