#include "autocal/io/calibration_block_fields.h"

namespace autocal {
namespace io {

namespace {

using Id = sensors::CalibrationBlockId;

// A block's setting in ProblemCalibration: a scalar or a three-vector one.
struct SettingField {
  const char* key;  // in the problem file
  ScalarBlockSetting* scalar = nullptr;
  VectorBlockSetting* vector = nullptr;
};

SettingField SettingFieldOf(ProblemCalibration& c, Id id) {
  switch (id) {
    case Id::kLidarRotation:
      return {"T_I_L rotation", nullptr, &c.T_I_L.rotation};
    case Id::kLidarTranslation:
      return {"T_I_L translation", nullptr, &c.T_I_L.translation};
    case Id::kTimeOffset:
      return {"time_offset_lidar_imu_s", &c.time_offset_lidar_imu_s};
    case Id::kWheelRadiusLeft:
      return {"wheel_radius_left_m", &c.wheel_radius_left_m};
    case Id::kWheelRadiusRight:
      return {"wheel_radius_right_m", &c.wheel_radius_right_m};
    case Id::kTrackWidth:
      return {"track_width_m", &c.track_width_m};
    case Id::kVehicleRotation:
      return {"T_I_V rotation", nullptr, &c.T_I_V.rotation};
    case Id::kVehicleTranslation:
      return {"T_I_V translation", nullptr, &c.T_I_V.translation};
    case Id::kGnssLeverArm:
      return {"p_I_A_m", nullptr, &c.p_I_A_m};
    case Id::kWheelSpeedScaleLeft:
      return {"wheel_speed_scale_left", &c.wheel_speed_scale_left};
    case Id::kWheelSpeedScaleRight:
      return {"wheel_speed_scale_right", &c.wheel_speed_scale_right};
    case Id::kOdometrySpeedScale:
      return {"odometry_speed_scale", &c.odometry_speed_scale};
    case Id::kEffectiveTrack:
      return {"effective_track_m", &c.effective_track_m};
    case Id::kWheelTimeOffset:
      return {"time_offset_wheel_imu_s", &c.time_offset_wheel_imu_s};
    case Id::kGnssTimeOffset:
      break;
  }
  return {"time_offset_gnss_imu_s", &c.time_offset_gnss_imu_s};
}

// A block's uncertainty in CalibrationUncertainty: a scalar, a vector, or one half of a pose
// (whose six flags hold the rotation's first).
struct UncertaintyField {
  ScalarBlockInfo* scalar = nullptr;
  VectorBlockInfo* vector = nullptr;
  PoseBlockInfo* pose = nullptr;
  bool rotation = false;
};

UncertaintyField UncertaintyFieldOf(CalibrationUncertainty& u, Id id) {
  switch (id) {
    case Id::kLidarRotation:
      return {nullptr, nullptr, &u.T_I_L, true};
    case Id::kLidarTranslation:
      return {nullptr, nullptr, &u.T_I_L, false};
    case Id::kTimeOffset:
      return {&u.time_offset_lidar_imu_s};
    case Id::kWheelRadiusLeft:
      return {&u.wheel_radius_left_m};
    case Id::kWheelRadiusRight:
      return {&u.wheel_radius_right_m};
    case Id::kTrackWidth:
      return {&u.track_width_m};
    case Id::kVehicleRotation:
      return {nullptr, nullptr, &u.T_I_V, true};
    case Id::kVehicleTranslation:
      return {nullptr, nullptr, &u.T_I_V, false};
    case Id::kGnssLeverArm:
      return {nullptr, &u.p_I_A_m};
    case Id::kWheelSpeedScaleLeft:
      return {&u.wheel_speed_scale_left};
    case Id::kWheelSpeedScaleRight:
      return {&u.wheel_speed_scale_right};
    case Id::kOdometrySpeedScale:
      return {&u.odometry_speed_scale};
    case Id::kEffectiveTrack:
      return {&u.effective_track_m};
    case Id::kWheelTimeOffset:
      return {&u.time_offset_wheel_imu_s};
    case Id::kGnssTimeOffset:
      break;
  }
  return {&u.time_offset_gnss_imu_s};
}

}  // namespace

BlockModeAndSigma BlockSettingIn(const ProblemCalibration& problem, Id id) {
  const SettingField f = SettingFieldOf(const_cast<ProblemCalibration&>(problem), id);
  if (f.scalar) return {f.scalar->mode, Eigen::VectorXd::Constant(1, f.scalar->prior_sigma)};
  return {f.vector->mode, Eigen::VectorXd(f.vector->prior_sigma)};
}

const char* ProblemKey(Id id) {
  ProblemCalibration scratch;
  return SettingFieldOf(scratch, id).key;
}

void SetBlockSetting(Id id, const BlockModeAndSigma& setting, ProblemCalibration* problem) {
  const SettingField f = SettingFieldOf(*problem, id);
  if (f.scalar) {
    *f.scalar = {setting.mode, setting.prior_sigma(0)};
  } else {
    *f.vector = {setting.mode, Eigen::Vector3d(setting.prior_sigma)};
  }
}

BlockUncertainty UncertaintyIn(const CalibrationUncertainty& uncertainty, Id id) {
  const UncertaintyField f =
      UncertaintyFieldOf(const_cast<CalibrationUncertainty&>(uncertainty), id);
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
  const UncertaintyField f = UncertaintyFieldOf(*uncertainty, id);
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
  (f.rotation ? f.pose->sigma_rot_deg : f.pose->sigma_p_m) = Eigen::Vector3d(sigma);
  if (!observable) return;
  std::vector<bool>& flags = f.pose->observable;
  if (flags.size() < 6) flags.assign(6, flags.empty() || flags[0]);  // one flag: the whole pose
  const size_t first = f.rotation ? 0 : 3;
  for (size_t k = 0; k < observable->size(); ++k) flags[first + k] = (*observable)[k];
}

}  // namespace io
}  // namespace autocal
