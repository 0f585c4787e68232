#include "autocal/sensors/calibration_blocks.h"

#include <cmath>

#include "autocal/common/units.h"

namespace autocal {
namespace sensors {

namespace {

double* DataOf(Eigen::Quaterniond& q) { return q.coeffs().data(); }
double* DataOf(Eigen::Vector3d& v) { return v.data(); }
double* DataOf(double& x) { return &x; }
const double* DataOf(const Eigen::Quaterniond& q) { return q.coeffs().data(); }
const double* DataOf(const Eigen::Vector3d& v) { return v.data(); }
const double* DataOf(const double& x) { return &x; }

template <auto kMember>
double* Values(Calibration* c) {
  return DataOf(c->*kMember);
}
template <auto kMember>
const double* ConstValues(const Calibration& c) {
  return DataOf(c.*kMember);
}

using Id = CalibrationBlockId;
using M = BlockManifold;
using S = BlockSensor;

using Names = std::array<const char*, 3>;
constexpr Names kLidarRotationNames = {"LiDAR rotation about the IMU x axis (roll)",
                                       "LiDAR rotation about the IMU y axis (pitch)",
                                       "LiDAR rotation about the IMU z axis (yaw)"};
constexpr Names kLidarTranslationNames = {
    "LiDAR x translation (IMU frame)", "LiDAR y translation (IMU frame)",
    "LiDAR z translation (IMU frame; planar driving rotates about it only)"};
// q_I_V is perturbed on the right, q_I_V * Exp(delta): delta is about the vehicle's axes.
constexpr Names kVehicleRotationNames = {"mount roll (about the vehicle's forward axis)",
                                         "mount pitch (about the vehicle's left axis)",
                                         "mount yaw (about the vehicle's up axis)"};
constexpr Names kVehicleTranslationNames = {"rear-axle x position (IMU frame)",
                                            "rear-axle y position (IMU frame)",
                                            "rear-axle z position (IMU frame)"};
constexpr Names kLeverArmNames = {"GNSS antenna x lever arm (IMU frame)",
                                  "GNSS antenna y lever arm (IMU frame)",
                                  "GNSS antenna z lever arm (IMU frame)"};

// Row fields: id, key, name, sensor, manifold, ambient and tangent size, value unit, display
// scale and unit, direction names, calibration_per_iteration.csv prefix, accessors.
// clang-format off
constexpr std::array<CalibrationBlockInfo, kNumCalibrationBlocks> kBlocks = {{
    {Id::kLidarRotation, "q_I_L", "T_I_L rotation", S::kLidar, M::kRightQuaternion, 4, 3, "",
     kRadToDeg, "deg", kLidarRotationNames, "q",
     Values<&Calibration::q_I_L>, ConstValues<&Calibration::q_I_L>},
    {Id::kLidarTranslation, "p_I_L", "T_I_L translation", S::kLidar, M::kEuclidean, 3, 3, "m",
     100.0, "cm", kLidarTranslationNames, "p",
     Values<&Calibration::p_I_L>, ConstValues<&Calibration::p_I_L>},
    {Id::kTimeOffset, "time_offset_lidar_imu_s", "LiDAR-IMU time offset", S::kLidar,
     M::kEuclidean, 1, 1, "", 1e3, "ms", {"LiDAR-IMU time offset"}, "",
     Values<&Calibration::time_offset_lidar_imu_s>,
     ConstValues<&Calibration::time_offset_lidar_imu_s>},
    {Id::kWheelRadiusLeft, "wheel_radius_left_m", "left rear wheel radius", S::kWheel,
     M::kEuclidean, 1, 1, "", 1e3, "mm", {"left rear wheel radius"}, "",
     Values<&Calibration::wheel_radius_left_m>, ConstValues<&Calibration::wheel_radius_left_m>},
    {Id::kWheelRadiusRight, "wheel_radius_right_m", "right rear wheel radius", S::kWheel,
     M::kEuclidean, 1, 1, "", 1e3, "mm", {"right rear wheel radius"}, "",
     Values<&Calibration::wheel_radius_right_m>, ConstValues<&Calibration::wheel_radius_right_m>},
    {Id::kTrackWidth, "track_width_m", "track width", S::kWheel, M::kEuclidean, 1, 1, "",
     1e3, "mm", {"track width"}, "",
     Values<&Calibration::track_width_m>, ConstValues<&Calibration::track_width_m>},
    {Id::kVehicleRotation, "q_I_V", "T_I_V rotation", S::kWheel, M::kRightQuaternion, 4, 3, "",
     kRadToDeg, "deg", kVehicleRotationNames, "qv_",
     Values<&Calibration::q_I_V>, ConstValues<&Calibration::q_I_V>},
    {Id::kVehicleTranslation, "p_I_V", "T_I_V translation", S::kWheel, M::kEuclidean, 3, 3, "m",
     100.0, "cm", kVehicleTranslationNames, "pv_",
     Values<&Calibration::p_I_V>, ConstValues<&Calibration::p_I_V>},
    {Id::kGnssLeverArm, "p_I_A", "GNSS lever arm", S::kGnss, M::kEuclidean, 3, 3, "m",
     100.0, "cm", kLeverArmNames, "pa_",
     Values<&Calibration::p_I_A>, ConstValues<&Calibration::p_I_A>},
    {Id::kWheelSpeedScaleLeft, "wheel_speed_scale_left", "left rear wheel speed scale",
     S::kWheel, M::kEuclidean, 1, 1, "", 100.0, "%", {"left rear wheel speed scale"}, "",
     Values<&Calibration::wheel_speed_scale_left>,
     ConstValues<&Calibration::wheel_speed_scale_left>},
    {Id::kWheelSpeedScaleRight, "wheel_speed_scale_right", "right rear wheel speed scale",
     S::kWheel, M::kEuclidean, 1, 1, "", 100.0, "%", {"right rear wheel speed scale"}, "",
     Values<&Calibration::wheel_speed_scale_right>,
     ConstValues<&Calibration::wheel_speed_scale_right>},
    {Id::kOdometrySpeedScale, "odometry_speed_scale", "odometry speed scale", S::kWheel,
     M::kEuclidean, 1, 1, "", 100.0, "%", {"odometry speed scale"}, "",
     Values<&Calibration::odometry_speed_scale>, ConstValues<&Calibration::odometry_speed_scale>},
    {Id::kEffectiveTrack, "effective_track_m", "effective track", S::kWheel, M::kEuclidean, 1, 1,
     "", 1e3, "mm", {"effective (slip) track"}, "",
     Values<&Calibration::effective_track_m>, ConstValues<&Calibration::effective_track_m>},
    {Id::kWheelTimeOffset, "time_offset_wheel_imu_s", "wheel-IMU time offset", S::kWheel,
     M::kEuclidean, 1, 1, "", 1e3, "ms", {"wheel-IMU time offset"}, "",
     Values<&Calibration::time_offset_wheel_imu_s>,
     ConstValues<&Calibration::time_offset_wheel_imu_s>},
    {Id::kGnssTimeOffset, "time_offset_gnss_imu_s", "GNSS-IMU time offset", S::kGnss,
     M::kEuclidean, 1, 1, "", 1e3, "ms", {"GNSS-IMU time offset"}, "",
     Values<&Calibration::time_offset_gnss_imu_s>,
     ConstValues<&Calibration::time_offset_gnss_imu_s>},
}};
// clang-format on

// Column names: a scalar's key, else prefix + axis (+ "_" + unit), axes x y z (w).
std::vector<std::string> Columns(const CalibrationBlockInfo& block, const std::string& prefix) {
  if (block.ambient_size == 1) return {block.key};
  const std::string unit = *block.value_unit ? std::string("_") + block.value_unit : "";
  const char* axes[4] = {"x", "y", "z", "w"};
  std::vector<std::string> out;
  for (int i = 0; i < block.ambient_size; ++i) out.push_back(prefix + axes[i] + unit);
  return out;
}

}  // namespace

const std::array<CalibrationBlockInfo, kNumCalibrationBlocks>& CalibrationBlocks() {
  return kBlocks;
}

const CalibrationBlockInfo& CalibrationBlock(CalibrationBlockId id) {
  return kBlocks[static_cast<size_t>(id)];
}

const CalibrationBlockInfo* FindCalibrationBlock(const std::string& key) {
  for (const CalibrationBlockInfo& block : kBlocks) {
    if (key == block.key) return &block;
  }
  return nullptr;
}

bool BlockInWheelForm(CalibrationBlockId id, WheelForm form) {
  switch (id) {
    case Id::kWheelRadiusLeft:
    case Id::kWheelRadiusRight:
      return form == WheelForm::kAngularRates;
    case Id::kTrackWidth:
      return form != WheelForm::kSpeedYawRate;
    case Id::kWheelSpeedScaleLeft:
    case Id::kWheelSpeedScaleRight:
      return form == WheelForm::kLinearSpeeds;
    case Id::kOdometrySpeedScale:
    case Id::kEffectiveTrack:
      return form == WheelForm::kSpeedYawRate;
    case Id::kLidarRotation:
    case Id::kLidarTranslation:
    case Id::kTimeOffset:
    case Id::kVehicleRotation:
    case Id::kVehicleTranslation:
    case Id::kGnssLeverArm:
    case Id::kWheelTimeOffset:
    case Id::kGnssTimeOffset:
      break;
  }
  return true;
}

std::vector<std::string> ValueColumns(const CalibrationBlockInfo& block) {
  return Columns(block, std::string(block.key) + "_");
}

std::vector<std::string> IterationColumns(const CalibrationBlockInfo& block) {
  return Columns(block, block.iteration_column_prefix);
}

}  // namespace sensors
}  // namespace autocal
