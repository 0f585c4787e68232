#include "autocal/io/calibration_block_fields.h"

#include <algorithm>
#include <cstddef>
#include <optional>

namespace autocal {
namespace io {

namespace {

using Id = sensors::CalibrationBlockId;

// Where a block lives: its key in a problem file, its setting there (a scalar or a
// three-vector one) and its part of an uncertainty (a scalar, a vector, or one half of a pose,
// whose six flags hold the rotation's first).
struct BlockFields {
  const char* key;
  ScalarBlockSetting* scalar_setting = nullptr;
  VectorBlockSetting* vector_setting = nullptr;
  ScalarBlockInfo* scalar = nullptr;
  VectorBlockInfo* vector = nullptr;
  PoseBlockInfo* pose = nullptr;
  bool rotation = false;
};

BlockFields Scalar(const char* key, ScalarBlockSetting* setting, ScalarBlockInfo* info) {
  return {key, setting, nullptr, info};
}
BlockFields PoseHalf(const char* key, VectorBlockSetting* setting, PoseBlockInfo* info,
                     bool rotation) {
  return {key, nullptr, setting, nullptr, nullptr, info, rotation};
}

// The one map from a block to its fields, in `p` and `u`.
BlockFields FieldsOf(Id id, ProblemCalibration& p, CalibrationUncertainty& u) {
  switch (id) {
    case Id::kLidarRotation:
      return PoseHalf("T_I_L rotation", &p.T_I_L.rotation, &u.T_I_L, true);
    case Id::kLidarTranslation:
      return PoseHalf("T_I_L translation", &p.T_I_L.translation, &u.T_I_L, false);
    case Id::kTimeOffset:
      return Scalar("time_offset_lidar_imu_s", &p.time_offset_lidar_imu_s,
                    &u.time_offset_lidar_imu_s);
    case Id::kWheelRadiusLeft:
      return Scalar("wheel_radius_left_m", &p.wheel_radius_left_m, &u.wheel_radius_left_m);
    case Id::kWheelRadiusRight:
      return Scalar("wheel_radius_right_m", &p.wheel_radius_right_m, &u.wheel_radius_right_m);
    case Id::kTrackWidth:
      return Scalar("track_width_m", &p.track_width_m, &u.track_width_m);
    case Id::kVehicleRotation:
      return PoseHalf("T_I_V rotation", &p.T_I_V.rotation, &u.T_I_V, true);
    case Id::kVehicleTranslation:
      return PoseHalf("T_I_V translation", &p.T_I_V.translation, &u.T_I_V, false);
    case Id::kGnssLeverArm:
      return {"p_I_A_m", nullptr, &p.p_I_A_m, nullptr, &u.p_I_A_m};
    case Id::kWheelSpeedScaleLeft:
      return Scalar("wheel_speed_scale_left", &p.wheel_speed_scale_left, &u.wheel_speed_scale_left);
    case Id::kWheelSpeedScaleRight:
      return Scalar("wheel_speed_scale_right", &p.wheel_speed_scale_right,
                    &u.wheel_speed_scale_right);
    case Id::kOdometrySpeedScale:
      return Scalar("odometry_speed_scale", &p.odometry_speed_scale, &u.odometry_speed_scale);
    case Id::kEffectiveTrack:
      return Scalar("effective_track_m", &p.effective_track_m, &u.effective_track_m);
    case Id::kWheelTimeOffset:
      return Scalar("time_offset_wheel_imu_s", &p.time_offset_wheel_imu_s,
                    &u.time_offset_wheel_imu_s);
    case Id::kGnssTimeOffset:
      break;
  }
  return Scalar("time_offset_gnss_imu_s", &p.time_offset_gnss_imu_s, &u.time_offset_gnss_imu_s);
}

// FieldsOf for one of the two structs, the other a scratch one.
BlockFields FieldsIn(Id id, ProblemCalibration& p) {
  CalibrationUncertainty unused;
  return FieldsOf(id, p, unused);
}
BlockFields FieldsIn(Id id, CalibrationUncertainty& u) {
  ProblemCalibration unused;
  return FieldsOf(id, unused, u);
}

}  // namespace

BlockModeAndSigma BlockSettingIn(const ProblemCalibration& problem, Id id) {
  const BlockFields f = FieldsIn(id, const_cast<ProblemCalibration&>(problem));
  if (f.scalar_setting) {
    return {f.scalar_setting->mode, Eigen::VectorXd::Constant(1, f.scalar_setting->prior_sigma)};
  }
  return {f.vector_setting->mode, Eigen::VectorXd(f.vector_setting->prior_sigma)};
}

const char* ProblemKey(Id id) {
  ProblemCalibration scratch;
  return FieldsIn(id, scratch).key;
}

void SetBlockSetting(Id id, const BlockModeAndSigma& setting, ProblemCalibration* problem) {
  const BlockFields f = FieldsIn(id, *problem);
  if (f.scalar_setting) {
    *f.scalar_setting = {setting.mode, setting.prior_sigma(0)};
  } else {
    *f.vector_setting = {setting.mode, Eigen::Vector3d(setting.prior_sigma)};
  }
}

BlockUncertainty UncertaintyIn(const CalibrationUncertainty& uncertainty, Id id) {
  const BlockFields f = FieldsIn(id, const_cast<CalibrationUncertainty&>(uncertainty));
  BlockUncertainty out;
  if (f.scalar) {
    if (f.scalar->sigma) out.sigma = Eigen::VectorXd::Constant(1, *f.scalar->sigma);
    if (f.scalar->observable) out.observable = {*f.scalar->observable};
    return out;
  }
  if (f.vector) {
    if (f.vector->sigma) out.sigma = Eigen::VectorXd(*f.vector->sigma);
    out.observable = f.vector->observable;
    return out;
  }
  const std::optional<Eigen::Vector3d>& sigma =
      f.rotation ? f.pose->sigma_rot_deg : f.pose->sigma_p_m;
  if (sigma) out.sigma = Eigen::VectorXd(*sigma);
  out.observable = f.pose->observable;
  if (out.observable.size() == 6) {
    const auto first = out.observable.begin() + (f.rotation ? 0 : 3);
    out.observable = std::vector<bool>(first, first + 3);
  }
  return out;
}

void SetBlockUncertainty(Id id, const Eigen::VectorXd& sigma, const std::vector<bool>* observable,
                         CalibrationUncertainty* uncertainty) {
  const BlockFields f = FieldsIn(id, *uncertainty);
  if (f.scalar) {
    f.scalar->sigma = sigma(0);
    if (observable) f.scalar->observable = (*observable)[0];
    return;
  }
  if (f.vector) {
    f.vector->sigma = Eigen::Vector3d(sigma);
    if (observable) f.vector->observable = *observable;
    return;
  }
  std::optional<Eigen::Vector3d>& half_sigma =
      f.rotation ? f.pose->sigma_rot_deg : f.pose->sigma_p_m;
  const bool other_estimated = (f.rotation ? f.pose->sigma_p_m : f.pose->sigma_rot_deg).has_value();
  const bool newly_estimated = !half_sigma.has_value();
  half_sigma = Eigen::Vector3d(sigma);
  std::vector<bool>& flags = f.pose->observable;
  const size_t first = f.rotation ? 0 : 3, other = 3 - first;
  if (!observable) {
    // A half without flags counts as observable (as a pose without any does); six flags that
    // were written while it had no sigma say "not estimated" for it, which no longer holds.
    if (flags.size() == 6 && newly_estimated) {
      std::fill(flags.begin() + static_cast<std::ptrdiff_t>(first),
                flags.begin() + static_cast<std::ptrdiff_t>(first + 3), true);
    }
    return;
  }
  if (flags.size() < 6) {
    // One flag is the whole pose's; none says the same as true. Either holds for the other
    // half only when it was estimated: a half without sigma (the problem fixes it) is not
    // observable.
    const bool whole = flags.empty() || flags[0];
    flags.assign(6, false);
    for (size_t k = 0; k < 3; ++k) flags[other + k] = whole && other_estimated;
  }
  for (size_t k = 0; k < observable->size(); ++k) flags[first + k] = (*observable)[k];
}

}  // namespace io
}  // namespace autocal
