#include "autocal/evaluation/calibration_errors.h"

#include <cmath>
#include <string>

#include "autocal/common/error.h"
#include "autocal/common/units.h"
#include "autocal/geometry/so3.h"

namespace autocal {
namespace evaluation {
namespace {

// 100 (estimate − truth) / truth, for quantities that are positive by nature.
double PercentError(double estimate, double truth, const char* name) {
  if (!(truth > 0.0)) {
    throw Error(std::string("cannot give the relative error of ") + name + ": its true value is " +
                std::to_string(truth) + " (must be > 0)");
  }
  return 100.0 * (estimate - truth) / truth;
}

}  // namespace

PoseError ComparePose(const Eigen::Quaterniond& q_estimate, const Eigen::Vector3d& p_estimate,
                      const Eigen::Quaterniond& q_truth, const Eigen::Vector3d& p_truth) {
  PoseError error;
  // q_est = q_true ⊗ Exp(δ)  =>  δ = Log(q_true⁻¹ ⊗ q_est).
  error.rotation_deg =
      kRadToDeg * geometry::Log(Eigen::Quaterniond(q_truth.conjugate() * q_estimate));
  error.translation_mm = 1e3 * (p_estimate - p_truth);
  return error;
}

CalibrationErrors CompareCalibration(const sensors::Calibration& estimate,
                                     const sensors::Calibration& truth) {
  CalibrationErrors errors;
  errors.T_I_L = ComparePose(estimate.q_I_L, estimate.p_I_L, truth.q_I_L, truth.p_I_L);
  errors.time_offset_ms = 1e3 * (estimate.time_offset_lidar_imu_s - truth.time_offset_lidar_imu_s);
  errors.wheel_radius_left_percent =
      PercentError(estimate.wheel_radius_left_m, truth.wheel_radius_left_m, "wheel_radius_left_m");
  errors.wheel_radius_right_percent = PercentError(
      estimate.wheel_radius_right_m, truth.wheel_radius_right_m, "wheel_radius_right_m");
  errors.track_width_percent =
      PercentError(estimate.track_width_m, truth.track_width_m, "track_width_m");
  errors.wheel_speed_scale_left_percent = PercentError(
      estimate.wheel_speed_scale_left, truth.wheel_speed_scale_left, "wheel_speed_scale_left");
  errors.wheel_speed_scale_right_percent = PercentError(
      estimate.wheel_speed_scale_right, truth.wheel_speed_scale_right, "wheel_speed_scale_right");
  errors.odometry_speed_scale_percent = PercentError(
      estimate.odometry_speed_scale, truth.odometry_speed_scale, "odometry_speed_scale");
  errors.effective_track_percent =
      PercentError(estimate.effective_track_m, truth.effective_track_m, "effective_track_m");
  errors.p_I_A_mm = 1e3 * (estimate.p_I_A - truth.p_I_A);
  errors.T_I_V = ComparePose(estimate.q_I_V, estimate.p_I_V, truth.q_I_V, truth.p_I_V);
  errors.wheel_time_offset_ms =
      1e3 * (estimate.time_offset_wheel_imu_s - truth.time_offset_wheel_imu_s);
  errors.gnss_time_offset_ms =
      1e3 * (estimate.time_offset_gnss_imu_s - truth.time_offset_gnss_imu_s);
  return errors;
}

}  // namespace evaluation
}  // namespace autocal
