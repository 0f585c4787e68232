#include "clock_initialization.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <optional>
#include <string>
#include <vector>

#include "autocal/common/time.h"
#include "autocal/common/units.h"
#include "autocal/estimation/mount_initialization.h"
#include "autocal/geometry/so3.h"
#include "autocal/sensors/imu_scatter.h"
#include "autocal/sensors/sample_timing.h"
#include "calibration_steps.h"

namespace autocal {
namespace pipeline {

namespace {

// The mount turned by the least rotation that takes its up axis onto up_I.
Eigen::Quaterniond WithUpAxis(const Eigen::Quaterniond& q_I_V, const Eigen::Vector3d& up_I) {
  return (Eigen::Quaterniond::FromTwoVectors(q_I_V * Eigen::Vector3d::UnitZ(), up_I) * q_I_V)
      .normalized();
}

// "-391.2 ms".
std::string Ms(double seconds) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.1f ms", seconds * 1e3);
  return text;
}

// Appends one speed and yaw-rate sample per wheel sample from the pair (left, right) scaled by
// (scale_left, scale_right) over the track `track_m`.
template <typename Samples, typename Pair>
void FromWheelPair(const Samples& samples, double scale_left, double scale_right, double track_m,
                   Pair pair, estimation::ScalarSeries* speed, estimation::ScalarSeries* yaw) {
  for (const auto& sample : samples) {
    const auto [left, right] = pair(sample);
    speed->push_back({sample.t_ns, 0.5 * (scale_left * left + scale_right * right)});
    yaw->push_back({sample.t_ns, (scale_right * right - scale_left * left) / track_m});
  }
}

}  // namespace

void WheelSpeedAndYawRate(const io::Dataset& dataset, const sensors::Calibration& c,
                          estimation::ScalarSeries* speed_m_s,
                          estimation::ScalarSeries* yaw_rate_rad_s) {
  speed_m_s->clear();
  yaw_rate_rad_s->clear();
  switch (dataset.wheel_form()) {
    case sensors::WheelForm::kAngularRates:
      return FromWheelPair(
          dataset.wheel, c.wheel_radius_left_m, c.wheel_radius_right_m, c.track_width_m,
          [](const sensors::WheelSample& w) { return std::pair(w.left_rad_s, w.right_rad_s); },
          speed_m_s, yaw_rate_rad_s);
    case sensors::WheelForm::kLinearSpeeds:
      return FromWheelPair(
          dataset.wheel_speeds, c.wheel_speed_scale_left, c.wheel_speed_scale_right,
          c.track_width_m,
          [](const sensors::WheelSpeedSample& w) { return std::pair(w.left_m_s, w.right_m_s); },
          speed_m_s, yaw_rate_rad_s);
    case sensors::WheelForm::kSpeedYawRate:
      break;
  }
  // The yaw rate's scale k_v b_ctrl / b_eff does not change a correlation: k_v alone is used.
  for (const sensors::OdometrySample& o : dataset.odometry) {
    speed_m_s->push_back({o.t_ns, c.odometry_speed_scale * o.speed_m_s});
    yaw_rate_rad_s->push_back({o.t_ns, c.odometry_speed_scale * o.yaw_rate_rad_s});
  }
}

namespace {

// A wheel clock the problem fixes, checked against the cross-correlation (docs/calibration.md,
// "Clocks in the offline calibration"): a warning when a reliable estimate lies farther from
// the fixed value than the check allows, empty otherwise. The yaw rates are allowed two sample
// intervals of the slower series; the forward accelerations, both smoothed over
// accel_smoothing_s, half that window. Both are wide of what synthetic series show, so that
// only a clock clearly off is named.
std::optional<std::string> FixedWheelClockContradicted(double fixed_s,
                                                       const estimation::WheelImuOffset& wheel) {
  const estimation::SeriesOffsetEstimate& e = wheel.estimate;
  const double interval_s = e.slower_interval_s;
  const double tolerance_s =
      wheel.yaw_rate.reliable
          ? 2.0 * interval_s
          : std::max(2.0 * interval_s, 0.5 * estimation::WheelImuOffsetOptions().accel_smoothing_s);
  if (!e.reliable || !(std::abs(e.offset_s - fixed_s) > tolerance_s)) return std::nullopt;
  return "the wheel-IMU time offset is fixed at " + Ms(fixed_s) +
         ", but the cross-correlation of the wheels' " + wheel.signal +
         " with the IMU puts it at " + Ms(e.offset_s) + ", more than the " + Ms(tolerance_s) +
         " the check allows: estimate it (time_offset_wheel_imu_s: estimate in the problem file) "
         "or correct its nominal value";
}

// InitializeClockOffsets with the wheels' speed and yaw rate (WheelSpeedAndYawRate; empty
// without wheels in the problem).
ClockInitialization ClockOffsetsFrom(const io::Dataset& dataset, const io::Problem& problem,
                                     const estimation::ScalarSeries& speed,
                                     const estimation::ScalarSeries& yaw_rate,
                                     sensors::Calibration* calibration,
                                     std::vector<std::string>* warnings) {
  ClockInitialization out;
  const io::ProblemCalibration& b = problem.calibration;
  if (problem.sensors.wheel && !speed.empty()) {
    const estimation::WheelImuOffset wheel =
        estimation::EstimateWheelImuOffset(dataset.imu, speed, yaw_rate, calibration->q_I_V);
    const estimation::SeriesOffsetEstimate& e = wheel.estimate;
    if (!Estimated(b.time_offset_wheel_imu_s.mode)) {
      if (const auto warning =
              FixedWheelClockContradicted(calibration->time_offset_wheel_imu_s, wheel)) {
        warnings->push_back(*warning);
      }
    } else if (e.reliable) {
      calibration->time_offset_wheel_imu_s = e.offset_s;
      out.wheel = wheel;
    } else {
      warnings->push_back("initialization: the wheel-IMU time offset keeps its nominal " +
                          Ms(calibration->time_offset_wheel_imu_s) +
                          ": the cross-correlation of the wheels' " + wheel.signal +
                          " with the IMU is not reliable (" + e.reason + ")");
      out.wheel = wheel;
    }
  }
  if (problem.sensors.gnss && Estimated(b.time_offset_gnss_imu_s.mode) && !dataset.gnss.empty()) {
    if (speed.empty()) {
      warnings->push_back("initialization: the GNSS-IMU time offset keeps its nominal " +
                          Ms(calibration->time_offset_gnss_imu_s) +
                          ": its cross-correlation compares the track's speed with the wheel "
                          "speed, and the problem has no wheel data");
      return out;
    }
    out.gnss = estimation::EstimateGnssImuOffset(
        dataset.gnss, estimation::Shifted(speed, calibration->time_offset_wheel_imu_s));
    if (out.gnss->reliable) {
      calibration->time_offset_gnss_imu_s = out.gnss->offset_s;
    } else {
      warnings->push_back("initialization: the GNSS-IMU time offset keeps its nominal " +
                          Ms(calibration->time_offset_gnss_imu_s) +
                          ": the cross-correlation of the track's speed with the wheel speed is "
                          "not reliable (" +
                          out.gnss->reason + ")");
    }
  }
  return out;
}

}  // namespace

ClockInitialization InitializeClockOffsets(const io::Dataset& dataset, const io::Problem& problem,
                                           sensors::Calibration* calibration,
                                           std::vector<std::string>* warnings) {
  estimation::ScalarSeries speed, yaw_rate;
  if (problem.sensors.wheel) WheelSpeedAndYawRate(dataset, *calibration, &speed, &yaw_rate);
  return ClockOffsetsFrom(dataset, problem, speed, yaw_rate, calibration, warnings);
}

ClockInitialization InitializeMountAndClocks(const io::Dataset& dataset, const io::Problem& problem,
                                             double max_nominal_deg,
                                             sensors::Calibration* calibration,
                                             sensors::Calibration* prior_centre,
                                             std::vector<std::string>* warnings) {
  const bool mount_wanted = problem.sensors.wheel &&
                            Estimated(problem.calibration.T_I_V.rotation.mode) &&
                            dataset.wheel_sample_count() > 0;
  if (!mount_wanted) return InitializeClockOffsets(dataset, problem, calibration, warnings);
  const estimation::UpAxisEstimate up = estimation::EstimateUpAxis(dataset.imu);
  if (!up.ok) {
    warnings->push_back("initialization: the IMU mount keeps its nominal value: " + up.problem);
    return InitializeClockOffsets(dataset, problem, calibration, warnings);
  }
  const Eigen::Quaterniond nominal = calibration->q_I_V;
  calibration->q_I_V = WithUpAxis(nominal, up.up_I);  // the wheel clock needs the up axis
  // The series depend on the wheel intrinsics only: computed once for the clocks and the mount.
  estimation::ScalarSeries speed, yaw_rate;
  WheelSpeedAndYawRate(dataset, *calibration, &speed, &yaw_rate);
  ClockInitialization clocks =
      ClockOffsetsFrom(dataset, problem, speed, yaw_rate, calibration, warnings);
  clocks.up = up;
  const estimation::MountInitialization mount =
      estimation::InitializeMount(dataset.imu, speed, calibration->time_offset_wheel_imu_s);
  for (const std::string& problem_text : mount.problems) {
    warnings->push_back("initialization: IMU mount: " + problem_text);
  }
  const double off_deg =
      mount.ok ? kRadToDeg * geometry::AngularDistance(nominal, mount.q_I_V) : 0.0;
  if (!mount.ok || off_deg <= max_nominal_deg) {
    calibration->q_I_V = nominal;  // a nominal within its prior: start and centre there
    return clocks;
  }
  // A nominal that is no guess: the data's mount is the start and the prior's centre.
  calibration->q_I_V = mount.q_I_V;
  prior_centre->q_I_V = mount.q_I_V;
  clocks.mount_from_data = true;
  char text[200];
  std::snprintf(text, sizeof(text),
                "initialization: the nominal IMU mount is %.1f deg from the one the data give "
                "(more than %.1f deg, three prior sigmas); the data's is used",
                off_deg, max_nominal_deg);
  warnings->push_back(text);
  return clocks;
}

namespace {

// One sensor's density for ImuNoiseFromData: the measured one when it is kMinImuNoiseScale
// times the stated one or more (a warning says so), else the stated one.
double DensityFromData(const char* sensor, const char* unit, double stated, double measured,
                       std::vector<std::string>* warnings) {
  if (!(measured >= kMinImuNoiseScale * stated)) return stated;
  char text[400];
  std::snprintf(
      text, sizeof(text),
      "IMU %s: its samples scatter %.3g %s from sample to sample (vibration and noise, Eq. N1), "
      "%.1f times sensors.yaml's noise density %.3g; the IMU factors use the measured "
      "density",
      sensor, measured, unit, measured / stated, stated);
  warnings->push_back(text);
  return measured;
}

// How far `value` strays from the chord over span_ns: the RMS, over the log, of its value midway
// between two samples span_ns apart less the mean of theirs, per axis, the largest axis.
template <typename Value>
double ChordDeviation(const sensors::ImuSamples& imu, int64_t span_ns, Value value) {
  Eigen::Vector3d sum_sq = Eigen::Vector3d::Zero();
  int64_t count = 0;
  size_t mid = 0, end = 0;
  for (size_t i = 0; i < imu.size(); ++i) {
    while (end < imu.size() && imu[end].t_ns < imu[i].t_ns + span_ns) ++end;
    while (mid < imu.size() && imu[mid].t_ns < imu[i].t_ns + span_ns / 2) ++mid;
    if (end == imu.size()) break;
    sum_sq += (value(imu[mid]) - 0.5 * (value(imu[i]) + value(imu[end]))).cwiseAbs2();
    ++count;
  }
  if (count == 0) return 0.0;
  return (sum_sq / static_cast<double>(count)).cwiseSqrt().maxCoeff();
}

// Eq. F5b's settings from the log: a dropout is an interval beyond Eq. T1's bracketing gap, and
// over one the rate and the specific force are taken off the interpolated line by as much as
// they stray from the chord over the log's longest dropout anywhere in the log (ChordDeviation:
// the motion's own spread at that span, which bounds it for the shorter dropouts).
void SetDropoutsFromData(const sensors::ImuSamples& imu, sensors::ImuNoise* noise) {
  if (imu.size() < 2) return;
  const sensors::SampleTiming timing = sensors::MeasureTiming(sensors::StampsOf(imu), "imu.csv");
  const double max_interval_s = sensors::MaxBracketingGapS(timing);
  if (!(timing.max_gap_s > max_interval_s)) return;
  const int64_t span_ns = SecondsToNs(timing.max_gap_s);
  noise->max_sample_interval_s = max_interval_s;
  noise->dropout_gyro_sigma_rad_s =
      ChordDeviation(imu, span_ns, [](const sensors::ImuSample& s) { return s.gyro_rad_s; });
  noise->dropout_accel_sigma_m_s2 =
      ChordDeviation(imu, span_ns, [](const sensors::ImuSample& s) { return s.accel_m_s2; });
}

}  // namespace

sensors::ImuNoise ImuNoiseFromData(const io::Dataset& dataset, std::vector<std::string>* warnings) {
  sensors::ImuNoise noise = dataset.sensors.imu.noise;
  SetDropoutsFromData(dataset.imu, &noise);
  const sensors::ImuScatter scatter = sensors::MeasureImuScatter(dataset.imu);
  noise.gyroscope_noise_density =
      DensityFromData("gyroscope", "rad/s/sqrt(Hz)", noise.gyroscope_noise_density,
                      scatter.gyroscope_noise_density(), warnings);
  noise.accelerometer_noise_density =
      DensityFromData("accelerometer", "m/s^2/sqrt(Hz)", noise.accelerometer_noise_density,
                      scatter.accelerometer_noise_density(), warnings);
  return noise;
}

const io::Dataset& WithImuNoiseFromData(const io::Dataset& dataset,
                                        std::optional<io::Dataset>* storage,
                                        std::vector<std::string>* warnings) {
  const sensors::ImuNoise noise = ImuNoiseFromData(dataset, warnings);
  const sensors::ImuNoise& stated = dataset.sensors.imu.noise;
  if (noise.gyroscope_noise_density == stated.gyroscope_noise_density &&
      noise.accelerometer_noise_density == stated.accelerometer_noise_density &&
      noise.max_sample_interval_s == stated.max_sample_interval_s) {
    return dataset;
  }
  storage->emplace(dataset);
  (*storage)->sensors.imu.noise = noise;
  return **storage;
}

double WheelNoiseScale(const io::Dataset& dataset, const sensors::Calibration& calibration,
                       const sensors::Calibration& nominal, std::vector<std::string>* warnings) {
  estimation::ScalarSeries speed, yaw_rate;
  WheelSpeedAndYawRate(dataset, calibration, &speed, &yaw_rate);
  const estimation::YawRateAgreement agreement =
      estimation::CompareYawRates(dataset.imu, speed, yaw_rate, calibration.time_offset_wheel_imu_s,
                                  calibration.q_I_V * Eigen::Vector3d::UnitZ());
  if (agreement.samples == 0) return 1.0;
  const double interval_s = SecondsBetween(yaw_rate.front().t_ns, yaw_rate.back().t_ns) /
                            static_cast<double>(yaw_rate.size() - 1);
  const double gyro_sigma =
      dataset.sensors.imu.noise.gyroscope_noise_density / std::sqrt(interval_s);
  estimation::KeyframeWheelOptions rows;
  SetWheelNoise(dataset, nominal, &rows);
  const double wheel_sigma = rows.factor.yaw_rate_sigma_rad_s;
  const double expected = std::hypot(wheel_sigma, gyro_sigma);
  const double scale = agreement.residual_sigma_rad_s / expected;
  if (!(scale >= kMinWheelNoiseScale)) return 1.0;
  char text[400];
  std::snprintf(text, sizeof(text),
                "wheels: their yaw rate explains the gyro's to %.3f rad/s (robust sigma over %zu "
                "samples, after a scale of %.2f) where %.3f rad/s was expected from the stated "
                "noise: the platform slips or the wheel data follow something else; every wheel "
                "row's sigma is scaled by %.1f",
                agreement.residual_sigma_rad_s, agreement.samples, agreement.scale, expected,
                scale);
  warnings->push_back(text);
  return scale;
}

void FuseUpAxisIntoMountPrior(const ClockInitialization& init, const io::Problem& problem,
                              double accel_bias_sigma_m_s2, double accel_random_walk_m_s3,
                              double gravity_m_s2, std::vector<estimation::EstimatedBlock>* blocks,
                              sensors::Calibration* prior_centre) {
  const auto block =
      std::find_if(blocks->begin(), blocks->end(), [](const estimation::EstimatedBlock& b) {
        return b.id == sensors::CalibrationBlockId::kVehicleRotation;
      });
  if (block == blocks->end()) return;
  const std::string centre = init.mount_from_data ? "the mount the data give" : "the nominal value";
  block->prior_source = centre;
  if (!init.up || !problem.calibration.ground_tilt_sigma_deg) return;
  const double ground_rad = *problem.calibration.ground_tilt_sigma_deg / kRadToDeg;
  const double bias_m_s2 =
      std::sqrt(accel_bias_sigma_m_s2 * accel_bias_sigma_m_s2 +
                accel_random_walk_m_s3 * accel_random_walk_m_s3 * init.up->span_s / 3.0);
  const double bias_rad = bias_m_s2 / gravity_m_s2;
  estimation::MountPrior prior;
  prior.q_I_V = Eigen::Quaterniond(block->prior.data()).normalized();
  prior.sigma_rad = block->prior_sigma;
  const estimation::MountPrior fused = estimation::FuseUpAxis(
      prior, init.up->up_I, std::sqrt(ground_rad * ground_rad + bias_rad * bias_rad));
  block->prior = Eigen::Map<const Eigen::Vector4d>(fused.q_I_V.coeffs().data());
  block->prior_sigma = fused.sigma_rad;
  block->prior_source = "its prior (" + centre + " and gravity's up axis)";
  Eigen::Map<Eigen::Quaterniond>(block->data) = fused.q_I_V;
  prior_centre->q_I_V = fused.q_I_V;
}

}  // namespace pipeline
}  // namespace autocal
