#include "problem_blocks.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

#include "autocal/common/units.h"
#include "autocal/io/calibration_block_fields.h"
#include "calibration_steps.h"

namespace autocal {
namespace pipeline {

namespace {

using Id = sensors::CalibrationBlockId;

// The options' weak default prior sigma and observability limit of a block, in file units.
struct BlockLimits {
  double default_prior_sigma;
  double max_observable_sigma;
};
// The weak default prior and observability limit of the speed scales (OfflineCalibrationOptions
// has none yet): a scale starts within 3 % of 1 and counts as observed to 0.1 %, as a 0.33 m
// radius does with the radius limits.
constexpr BlockLimits kSpeedScaleLimits = {0.03, 0.001};
// A skid-steer effective track lies between the wheel separation (the usual nominal value) and
// about twice it (the slip of a turn; 1.875 times it on a real robot), and it changes with the
// ground by more than a few percent: its default prior sigma is 0.75 times the nominal
// effective track (at least the track width's default), and it counts as observed to 5 % of
// it (at least the track width's limit). With 2 % the 300 s skid-steer preset (sigma 5 %
// after the solve) had it held at the physical track, 9 sigma from where the data put it.
constexpr double kEffectiveTrackPriorFraction = 0.75;
constexpr double kEffectiveTrackLimitFraction = 0.05;

BlockLimits EffectiveTrackLimits(double nominal_m, const OfflineCalibrationOptions& o) {
  return {std::max(o.default_track_width_prior_sigma_m, kEffectiveTrackPriorFraction * nominal_m),
          std::max(o.max_observable_track_width_sigma_m, kEffectiveTrackLimitFraction * nominal_m)};
}
// The wheel and GNSS clocks start from a cross-correlation searched over +-1 s
// (pipeline/clock_initialization.h): the weak default prior covers that range at 2 sigma. An
// offset counts as observed to 20 ms, the LiDAR's limit scaled by the slower sensors' rates (a
// 10 Hz GNSS or odometry interval is 100 ms; 20 ms moves a fix by 0.2 m at 10 m/s).
constexpr BlockLimits kClockOffsetLimits = {0.5, 0.02};

BlockLimits LimitsOf(Id id, const OfflineCalibrationOptions& o) {
  switch (id) {
    case Id::kLidarRotation:
      return {o.default_rotation_prior_sigma_deg, o.max_observable_rotation_sigma_deg};
    case Id::kLidarTranslation:
      return {o.default_translation_prior_sigma_m, o.max_observable_translation_sigma_m};
    case Id::kTimeOffset:
      return {o.default_time_offset_prior_sigma_s, o.max_observable_time_offset_sigma_s};
    case Id::kWheelRadiusLeft:
    case Id::kWheelRadiusRight:
      return {o.default_wheel_radius_prior_sigma_m, o.max_observable_wheel_radius_sigma_m};
    case Id::kTrackWidth:
      return {o.default_track_width_prior_sigma_m, o.max_observable_track_width_sigma_m};
    case Id::kVehicleRotation:
      return {o.default_rotation_prior_sigma_deg, o.max_observable_vehicle_rotation_sigma_deg};
    case Id::kVehicleTranslation:
      return {o.default_translation_prior_sigma_m, o.max_observable_vehicle_translation_sigma_m};
    case Id::kWheelSpeedScaleLeft:
    case Id::kWheelSpeedScaleRight:
    case Id::kOdometrySpeedScale:
      return kSpeedScaleLimits;
    case Id::kEffectiveTrack:  // the floor of EffectiveTrackLimits
      return {o.default_track_width_prior_sigma_m, o.max_observable_track_width_sigma_m};
    case Id::kWheelTimeOffset:
    case Id::kGnssTimeOffset:
      return kClockOffsetLimits;
    case Id::kGnssLeverArm:
      break;
  }
  return {o.default_translation_prior_sigma_m, o.max_observable_lever_arm_sigma_m};
}

BlockLimits LimitsOf(Id id, const io::SensorsConfig& sensors, const OfflineCalibrationOptions& o) {
  return id == Id::kEffectiveTrack
             ? EffectiveTrackLimits(sensors.nominal_calibration.effective_track_m, o)
             : LimitsOf(id, o);
}

// Prior sigma per direction in tangent units: the problem's for a block in prior mode, else
// the dataset's nominal uncertainty when it states one, else the default.
Eigen::VectorXd PriorSigma(const BlockSetting& setting, int size, double default_sigma,
                           double to_tangent) {
  if (setting.mode == io::BlockMode::kPrior) return setting.prior_sigma * to_tangent;
  if (setting.nominal_sigma) return *setting.nominal_sigma * to_tangent;
  return Eigen::VectorXd::Constant(size, default_sigma * to_tangent);
}

}  // namespace

BlockSetting SettingOf(Id id, const io::ProblemCalibration& p,
                       const io::CalibrationUncertainty& u) {
  const io::BlockModeAndSigma setting = io::BlockSettingIn(p, id);
  BlockSetting out;
  out.mode = setting.mode;
  out.prior_sigma = setting.prior_sigma;
  out.nominal_sigma = io::UncertaintyIn(u, id).sigma;
  return out;
}

double FileToTangent(const sensors::CalibrationBlockInfo& block) {
  return block.manifold == sensors::BlockManifold::kRightQuaternion ? 1.0 / kRadToDeg : 1.0;
}

bool SensorUsed(const sensors::CalibrationBlockInfo& block, bool use_wheel, bool use_gnss) {
  switch (block.sensor) {
    case sensors::BlockSensor::kWheel:
      return use_wheel;
    case sensors::BlockSensor::kGnss:
      return use_gnss;
    case sensors::BlockSensor::kLidar:
      break;
  }
  return true;
}

namespace {

// The blocks of `problem` of the sensors taking part whose mode is estimated (`estimated`) or
// fixed (otherwise), as EstimatedBlocks describes them.
std::vector<estimation::EstimatedBlock> BlocksOf(const io::Problem& problem,
                                                 const io::SensorsConfig& sensors,
                                                 const OfflineCalibrationOptions& o, bool use_wheel,
                                                 bool use_gnss, bool estimated,
                                                 sensors::Calibration* c) {
  const io::ProblemCalibration& p = problem.calibration;
  std::vector<estimation::EstimatedBlock> blocks;
  for (const sensors::CalibrationBlockInfo& info : sensors::CalibrationBlocks()) {
    const BlockSetting setting = SettingOf(info.id, p, sensors.nominal_uncertainty);
    if (!SensorUsed(info, use_wheel, use_gnss) || Estimated(setting.mode) != estimated) continue;
    const sensors::WheelForm form = sensors.wheel ? sensors.wheel->form : sensors::WheelForm();
    if (!sensors::BlockInWheelForm(info.id, form)) continue;
    if (info.id == Id::kWheelRadiusRight && p.wheel_radius_shared) continue;
    estimation::EstimatedBlock b = estimation::BlockOf(info.id, c);
    if (info.id == Id::kWheelRadiusLeft && p.wheel_radius_shared) {
      b.name = "rear wheel radius (both wheels)";
      b.direction_names = {b.name};
    }
    const double to_tangent = FileToTangent(info);
    const BlockLimits limits = LimitsOf(info.id, sensors, o);
    b.prior = Eigen::Map<const Eigen::VectorXd>(info.const_values(sensors.nominal_calibration),
                                                info.ambient_size);
    b.prior_sigma = PriorSigma(setting, info.tangent_size, limits.default_prior_sigma, to_tangent);
    b.prior_stated = setting.mode == io::BlockMode::kPrior || setting.nominal_sigma.has_value();
    b.max_observable_sigma = limits.max_observable_sigma * to_tangent;
    b.max_posterior_to_prior_sigma = o.max_posterior_to_prior_sigma;
    b.max_kept_sigma_to_limit = o.max_kept_sigma_to_limit;
    blocks.push_back(std::move(b));
  }
  return blocks;
}

}  // namespace

std::vector<estimation::EstimatedBlock> EstimatedBlocks(const io::Problem& problem,
                                                        const io::SensorsConfig& sensors,
                                                        const OfflineCalibrationOptions& o,
                                                        bool use_wheel, bool use_gnss,
                                                        sensors::Calibration* c) {
  return BlocksOf(problem, sensors, o, use_wheel, use_gnss, true, c);
}

std::vector<estimation::EstimatedBlock> FixedBlocks(const io::Problem& problem,
                                                    const io::SensorsConfig& sensors,
                                                    const OfflineCalibrationOptions& o,
                                                    bool use_wheel, bool use_gnss,
                                                    sensors::Calibration* c) {
  return BlocksOf(problem, sensors, o, use_wheel, use_gnss, false, c);
}

double DefaultPriorSigma(sensors::CalibrationBlockId id, const io::SensorsConfig& sensors,
                         const OfflineCalibrationOptions& options) {
  return LimitsOf(id, sensors, options).default_prior_sigma;
}

double ThreeSigmaPriorDeg(const std::vector<estimation::EstimatedBlock>& blocks, Id rotation) {
  for (const estimation::EstimatedBlock& b : blocks) {
    if (b.id == rotation) return 3.0 * b.prior_sigma.maxCoeff() * kRadToDeg;
  }
  return std::numeric_limits<double>::infinity();
}

double MaxNominalMountDeg(const io::Problem& problem, const io::SensorsConfig& sensors,
                          const OfflineCalibrationOptions& options) {
  sensors::Calibration scratch = sensors.nominal_calibration;
  return ThreeSigmaPriorDeg(EstimatedBlocks(problem, sensors, options, true, false, &scratch),
                            Id::kVehicleRotation);
}

void SetUncertainty(Id id, const Eigen::VectorXd& sigma, const std::vector<bool>* observable,
                    io::CalibrationUncertainty* u) {
  const bool rotation =
      sensors::CalibrationBlock(id).manifold == sensors::BlockManifold::kRightQuaternion;
  io::SetBlockUncertainty(id, rotation ? Eigen::VectorXd(sigma * kRadToDeg) : sigma, observable, u);
}

void FillUncertainty(const std::vector<estimation::EstimatedBlock>& blocks,
                     const estimation::BlockObservability& observability,
                     io::CalibrationUncertainty* u) {
  for (size_t i = 0; i < blocks.size(); ++i) {
    SetUncertainty(blocks[i].id, observability.sigma[i], &observability.observable[i], u);
  }
}

}  // namespace pipeline
}  // namespace autocal
