#include "online_without_lidar.h"

#include <algorithm>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/time.h"
#include "autocal/estimation/clock_offsets.h"
#include "autocal/estimation/gnss_inertial_keyframes.h"
#include "autocal/sensors/gnss_enu.h"
#include "calibration_steps.h"
#include "clock_initialization.h"
#include "problem_blocks.h"
#include "window_settings.h"

namespace autocal {
namespace pipeline {

namespace {

constexpr double kMinKeyframePeriodS = 0.05;
constexpr double kMaxKeyframePeriodS = 0.5;

}  // namespace

io::Dataset OnImuClock(const io::Dataset& dataset, io::Problem* problem,
                       sensors::Calibration* applied, std::vector<std::string>* warnings) {
  *applied = dataset.sensors.nominal_calibration;
  io::Dataset out = dataset;
  const ClockInitialization initialization = InitializeMountAndClocks(
      dataset, *problem, MaxNominalMountDeg(*problem, dataset.sensors, OfflineCalibrationOptions()),
      applied, &out.sensors.nominal_calibration, warnings);
  // The mount's prior centre with gravity's roll and pitch (Eq. C4), as offline.
  sensors::Calibration scratch = out.sensors.nominal_calibration;
  std::vector<estimation::EstimatedBlock> blocks =
      EstimatedBlocks(*problem, out.sensors, OfflineCalibrationOptions(), problem->sensors.wheel,
                      problem->sensors.gnss, &scratch);
  FuseUpAxisIntoMountPrior(initialization, *problem,
                           estimation::GnssInertialKeyframesOptions().accel_bias_prior_sigma_m_s2,
                           dataset.sensors.imu.noise.accelerometer_random_walk,
                           dataset.sensors.imu.gravity_m_s2, &blocks,
                           &out.sensors.nominal_calibration);
  applied->q_I_V = out.sensors.nominal_calibration.q_I_V;
  const auto apply = [&](double offset_s, io::ScalarBlockSetting* setting, const char* sensor) {
    if (offset_s == 0.0 && !Estimated(setting->mode)) return;
    char text[240];
    std::snprintf(
        text, sizeof(text),
        "the %s-IMU time offset is held at %.1f ms by the online estimator (%s; "
        "it is not refined while streaming)",
        sensor, offset_s * 1e3,
        Estimated(setting->mode) ? "initialized by cross-correlation" : "the nominal one");
    warnings->push_back(text);
    setting->mode = io::BlockMode::kFixed;
  };
  apply(applied->time_offset_wheel_imu_s, &problem->calibration.time_offset_wheel_imu_s, "wheel");
  apply(applied->time_offset_gnss_imu_s, &problem->calibration.time_offset_gnss_imu_s, "GNSS");
  out.wheel = estimation::Shifted(std::move(out.wheel), applied->time_offset_wheel_imu_s);
  out.wheel_speeds =
      estimation::Shifted(std::move(out.wheel_speeds), applied->time_offset_wheel_imu_s);
  out.odometry = estimation::Shifted(std::move(out.odometry), applied->time_offset_wheel_imu_s);
  out.gnss = estimation::Shifted(std::move(out.gnss), applied->time_offset_gnss_imu_s);
  out.sensors.nominal_calibration.time_offset_wheel_imu_s = 0.0;
  out.sensors.nominal_calibration.time_offset_gnss_imu_s = 0.0;
  return out;
}

int64_t KeyframePeriodWithoutLidar(const io::Dataset& dataset,
                                   const OnlineEstimationOptions& options) {
  if (options.keyframe_period_without_lidar_s > 0.0) {
    return SecondsToNs(options.keyframe_period_without_lidar_s);
  }
  std::vector<int64_t> intervals;
  for (size_t i = 1; i < dataset.gnss.size(); ++i) {
    intervals.push_back(dataset.gnss[i].t_ns - dataset.gnss[i - 1].t_ns);
  }
  if (intervals.empty()) {
    throw Error("dataset " + dataset.directory + ": gnss.csv has " +
                std::to_string(dataset.gnss.size()) +
                " fix; the online estimator without the LiDAR needs at least 2 to set its "
                "keyframe period");
  }
  std::nth_element(intervals.begin(), intervals.begin() + intervals.size() / 2, intervals.end());
  return std::clamp(intervals[intervals.size() / 2], SecondsToNs(kMinKeyframePeriodS),
                    SecondsToNs(kMaxKeyframePeriodS));
}

estimation::Keyframe StartWithoutLidar(const io::Dataset& dataset, const io::Problem& problem,
                                       const OnlineEstimationOptions& options,
                                       const TimingLimits& timing, int64_t period_ns,
                                       bool use_wheel,
                                       estimation::SlidingWindowOptions* window_options,
                                       std::vector<std::string>* warnings) {
  if (dataset.imu.empty() || dataset.gnss.empty()) {
    throw Error("dataset " + dataset.directory + ": " +
                (dataset.imu.empty() ? "imu.csv" : "gnss.csv") +
                " has no sample; the online estimator without the LiDAR starts from the IMU "
                "and the GNSS fixes");
  }
  const int64_t first_ns = std::max(dataset.imu.front().t_ns, dataset.gnss.front().t_ns);
  const int64_t last_ns = std::min({dataset.imu.back().t_ns, dataset.gnss.back().t_ns,
                                    first_ns + SecondsToNs(options.initialization_duration_s)});
  std::vector<estimation::Keyframe> keyframes =
      KeyframesEvery(dataset.imu, first_ns, last_ns, period_ns, warnings);
  if (keyframes.size() < 2) {
    throw Error("dataset " + dataset.directory +
                ": the IMU and the GNSS fixes overlap too briefly for two keyframes " +
                std::to_string(NsToSeconds(period_ns)) +
                " s apart; the online estimator without the LiDAR starts from them");
  }
  const sensors::EnuConverter enu = sensors::EnuConverter::AtFirstFix(dataset.gnss);
  estimation::GnssInertialKeyframesOptions gnss_inertial =
      GnssInertialStart(dataset, problem, timing);
  gnss_inertial.first_keyframe_covariance = true;
  const estimation::GnssInertialKeyframes start = estimation::KeyframesFromGnssAndImu(
      &keyframes, dataset.imu, StartWheelData(dataset, use_wheel), dataset.gnss, enu,
      dataset.sensors.nominal_calibration, gnss_inertial);
  SetGnssStart(enu, start, options, window_options, warnings);
  return keyframes.front();
}

}  // namespace pipeline
}  // namespace autocal
