#include "autocal/estimation/sliding_window_blocks.h"

#include <string>

#include "autocal/common/error.h"

namespace autocal {
namespace estimation {

SlidingWindowBlockSetting BlockSettingOf(sensors::CalibrationBlockId id,
                                         SlidingWindowEstimatedBlocks* e,
                                         SlidingWindowCalibrationPrior* p) {
  using Id = sensors::CalibrationBlockId;
  switch (id) {
    case Id::kLidarRotation:
      return {&e->extrinsic_rotation, &p->extrinsic_rotation_deg};
    case Id::kLidarTranslation:
      return {&e->extrinsic_translation, &p->extrinsic_translation_m};
    case Id::kTimeOffset:
      return {&e->time_offset, &p->time_offset_s};
    case Id::kWheelRadiusLeft:
    case Id::kWheelRadiusRight:
      return {&e->wheel_radii, &p->wheel_radius_m};
    case Id::kTrackWidth:
      return {&e->track_width, &p->track_width_m};
    case Id::kVehicleRotation:
      return {&e->vehicle_frame, &p->vehicle_rotation_deg};
    case Id::kVehicleTranslation:
      return {&e->vehicle_frame, &p->vehicle_translation_m};
    case Id::kGnssLeverArm:
      return {&e->gnss_lever_arm, &p->gnss_lever_arm_m};
    case Id::kOdometrySpeedScale:
      return {&e->odometry_speed_scale, &p->odometry_speed_scale};
    case Id::kEffectiveTrack:
      return {&e->effective_track, &p->effective_track_m};
    case Id::kWheelSpeedScaleLeft:
    case Id::kWheelSpeedScaleRight:
      return {&e->wheel_speed_scales, &p->wheel_speed_scale};
    case Id::kWheelTimeOffset:
    case Id::kGnssTimeOffset:
      break;
  }
  throw Error(std::string("calibration block ") + sensors::CalibrationBlock(id).key +
              " is not supported by the sliding window (it reads the wheels and the GNSS on "
              "the IMU clock; estimate the offsets offline)");
}

Eigen::VectorXd PriorSigmasOf(sensors::CalibrationBlockId id,
                              const SlidingWindowCalibrationPrior& prior) {
  SlidingWindowEstimatedBlocks unused;
  SlidingWindowCalibrationPrior p = prior;
  const double sigma = *BlockSettingOf(id, &unused, &p).prior_sigma;
  const auto axes = prior.axis_sigmas.find(id);
  if (axes != prior.axis_sigmas.end()) return axes->second;
  return Eigen::VectorXd::Constant(sensors::CalibrationBlock(id).tangent_size, sigma);
}

bool WindowSupports(sensors::CalibrationBlockId id) {
  using Id = sensors::CalibrationBlockId;
  return id != Id::kWheelTimeOffset && id != Id::kGnssTimeOffset;
}

bool Estimated(sensors::CalibrationBlockId id, const SlidingWindowEstimatedBlocks& estimate) {
  if (!WindowSupports(id)) return false;
  SlidingWindowEstimatedBlocks e = estimate;
  SlidingWindowCalibrationPrior unused;
  return *BlockSettingOf(id, &e, &unused).estimate;
}

}  // namespace estimation
}  // namespace autocal
