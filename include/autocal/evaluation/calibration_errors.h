#pragma once

// Errors of an estimated calibration against the truth (docs/evaluation.md, "Calibration").
// Every error is estimate minus truth, in the unit its name carries.

#include <Eigen/Core>

#include "autocal/sensors/calibration.h"

namespace autocal {
namespace evaluation {

// A pose block T_I_X. The rotation error is the right perturbation that takes the truth to
// the estimate, δ = Log(q_true⁻¹ ⊗ q_est) (README "rotation perturbation"), in degrees about
// the axes of X; the translation error p_est − p_true is in I, in millimetres.
struct PoseError {
  Eigen::Vector3d rotation_deg = Eigen::Vector3d::Zero();
  Eigen::Vector3d translation_mm = Eigen::Vector3d::Zero();

  double RotationAngleDeg() const { return rotation_deg.norm(); }
  double TranslationNormMm() const { return translation_mm.norm(); }
};

struct CalibrationErrors {
  PoseError T_I_L;
  double time_offset_ms = 0.0;  // offset_est − offset_true
  // 100 (x_est − x_true) / x_true.
  double wheel_radius_left_percent = 0.0;
  double wheel_radius_right_percent = 0.0;
  double track_width_percent = 0.0;
  // The blocks of the other wheel forms (sensors::Calibration): speed scales, k_v, b_eff.
  double wheel_speed_scale_left_percent = 0.0;
  double wheel_speed_scale_right_percent = 0.0;
  double odometry_speed_scale_percent = 0.0;
  double effective_track_percent = 0.0;
  Eigen::Vector3d p_I_A_mm = Eigen::Vector3d::Zero();  // lever arm, in I
  PoseError T_I_V;
  // The wheels' and the receiver's clocks: offset_est - offset_true.
  double wheel_time_offset_ms = 0.0;
  double gnss_time_offset_ms = 0.0;
};

PoseError ComparePose(const Eigen::Quaterniond& q_estimate, const Eigen::Vector3d& p_estimate,
                      const Eigen::Quaterniond& q_truth, const Eigen::Vector3d& p_truth);

// Throws autocal::Error when a true wheel radius, track width, speed scale or effective track
// is not positive.
CalibrationErrors CompareCalibration(const sensors::Calibration& estimate,
                                     const sensors::Calibration& truth);

}  // namespace evaluation
}  // namespace autocal
