#pragma once

// Initial time offsets of the wheel odometry and the GNSS receiver against the IMU, found by
// cross-correlating scalar signals that both clocks see (docs/calibration.md, "Clock
// offsets of the wheels and GNSS"). Sign as for the LiDAR: t_imu = t_sensor + offset_s, a sample
// stamped t by the sensor was measured at IMU-clock time t + offset_s. Odometry whose yaw rate lags
// the gyro by 0.38 s (its stamps come late) has offset_s = -0.38 s.
//
//   EstimateSeriesOffset   any two sampled scalar series with their own (jittered) rates;
//   EstimateWheelImuOffset wheel yaw rate vs the gyro about the vehicle's up axis, or on a
//                          straight drive the wheel speed's derivative vs the forward
//                          accelerometer;
//   EstimateGnssImuOffset  the GNSS track's horizontal speed vs the wheel speed.
// Each result says whether it can be trusted and, if not, why.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

#include "autocal/common/time.h"
#include "autocal/sensors/measurements.h"

namespace autocal {
namespace estimation {

// One sample of a scalar signal, stamped on its sensor's clock.
struct TimedValue {
  int64_t t_ns = 0;
  double value = 0.0;
};
// Samples in strictly increasing time.
using ScalarSeries = std::vector<TimedValue>;

struct SeriesOffsetOptions {
  double search_range_s = 1.0;  // offsets in [-range, +range] are tried
  // Grid step of the coarse scan; 0 chooses half the slower series' median interval (within
  // 2-50 ms). A fine scan around the coarse peak (within the search range) then uses a quarter
  // of the faster series' median interval (at least 0.5 ms) and a parabola through the peak.
  double step_s = 0.0;
  // Below this Pearson correlation at the peak the two signals do not agree well enough
  // (noise, too little variation, or not the same quantity) to trust the offset.
  double min_peak_correlation = 0.8;
  // Least standard deviation of each series (in its unit) over the compared samples: a
  // signal that hardly varies has no shape to align. 0 disables the check.
  double min_reference_std = 0.0;
  double min_sensor_std = 0.0;
  size_t min_pairs = 20;  // compared samples needed
};

struct SeriesOffsetEstimate {
  bool reliable = false;
  std::string reason;     // why not, when !reliable
  double offset_s = 0.0;  // t_reference = t_sensor + offset_s
  double peak_correlation = 0.0;
  size_t pairs = 0;  // samples compared at each candidate
  double reference_std = 0.0;
  double sensor_std = 0.0;
  double slower_interval_s = 0.0;  // the slower series' median interval (set once they overlap)
  std::vector<double> candidate_offsets_s;  // the coarse correlation curve, for reports
  std::vector<double> correlation;
};

// Finds the offset that best aligns `sensor` (stamped on its own clock) with `reference`
// (stamped on the reference clock, the IMU's): the series sampled more sparsely is compared,
// sample by sample, with the denser one linearly interpolated at the shifted stamp. Only
// samples whose shifted stamp stays inside the denser series for every candidate count, so
// that all candidates compare the same samples. Not reliable when the peak correlation is
// below min_peak_correlation, the peak lies at the edge of the range (the offset may be
// outside it), a series hardly varies, or too few samples overlap.
SeriesOffsetEstimate EstimateSeriesOffset(const ScalarSeries& reference, const ScalarSeries& sensor,
                                          const SeriesOffsetOptions& options = {});

// ---- Signals.

// The gyro's rate about `axis_I` (a unit vector in the IMU frame) at each IMU sample.
ScalarSeries GyroAbout(const sensors::ImuSamples& imu, const Eigen::Vector3d& axis_I);
// The accelerometer's specific force along `axis_I` at each IMU sample.
ScalarSeries AccelAlong(const sensors::ImuSamples& imu, const Eigen::Vector3d& axis_I);
// Central differences (v[i+1] - v[i-1]) / (t[i+1] - t[i-1]) at the inner samples.
ScalarSeries CentralDerivative(const ScalarSeries& series);
// Centred moving average over `width_s` (a symmetric filter: it delays nothing).
ScalarSeries MovingAverage(const ScalarSeries& series, double width_s);
// The same samples stamped offset_s later (onto the reference clock of that offset): a series
// here, or any vector of samples with an int64 t_ns (the dataset's wheel, odometry and GNSS).
template <typename Samples>
Samples Shifted(Samples samples, double offset_s) {
  const int64_t shift_ns = SecondsToNs(offset_s);
  for (auto& s : samples) s.t_ns += shift_ns;
  return samples;
}
// Linear interpolation at t_ns, clamped to the ends; `series` must not be empty.
double InterpolateSeries(const ScalarSeries& series, int64_t t_ns);

// ---- Wheel odometry against the IMU.

struct WheelImuOffsetOptions {
  SeriesOffsetOptions series;
  // The yaw rate is used when the wheel yaw rate varies by at least this much; below it
  // (a straight drive) the speed's derivative against the forward accelerometer.
  double min_yaw_rate_std_rad_s = 0.02;
  double min_accel_std_m_s2 = 0.05;  // the least variation of either acceleration signal
  // Both accelerations are averaged over this window first: the accelerometer's vibration
  // and the differentiated speed's quantization are far above the motion's own bandwidth.
  double accel_smoothing_s = 0.3;
};

struct WheelImuOffset {
  SeriesOffsetEstimate estimate;  // the chosen comparison; offset: t_imu = t_wheel + offset_s
  std::string signal;             // "yaw rate" or "forward acceleration"
  SeriesOffsetEstimate yaw_rate;  // both attempts, for reports (empty when not tried)
  SeriesOffsetEstimate acceleration;
};

// Wheel odometry as vehicle speed (m/s) and yaw rate (rad/s) on the wheel clock; wheels that
// report per-wheel rates give both through the nominal radii and track (their scale does not
// matter here). q_I_V is the mount (only its up axis is used for the yaw rate, its forward
// axis for the acceleration). The yaw rate is tried first when it varies enough, the
// acceleration when the yaw rate is flat or not reliable; the reliable one is returned.
WheelImuOffset EstimateWheelImuOffset(const sensors::ImuSamples& imu,
                                      const ScalarSeries& wheel_speed_m_s,
                                      const ScalarSeries& wheel_yaw_rate_rad_s,
                                      const Eigen::Quaterniond& q_I_V,
                                      const WheelImuOffsetOptions& options = {});

// How well the wheels' yaw rate explains the gyro's about the vehicle's up axis, once both are
// on one clock: gyro_up(t) = scale * yaw_wheel(t) + per_speed * v_wheel(t) + bias + e, least
// squares over the wheel samples inside the IMU's span, the gyro averaged over the wheels'
// mean interval around each. The scale absorbs a wrong track or a skid-steer robot's slip, the
// speed term the left and right wheels' different radii or speed scales (the factors estimate
// both); what is left, e, is noise the wheel factors must carry.
struct YawRateAgreement {
  size_t samples = 0;
  double scale = 0.0;
  double per_speed_rad_m = 0.0;
  double bias_rad_s = 0.0;
  double residual_sigma_rad_s = 0.0;  // robust: 1.4826 * median |e - median e|
};
// `offset_s` puts the wheel series (speed and yaw rate at the same stamps) on the IMU clock
// (t_imu = t_wheel + offset_s). Fewer than ten samples, or series that do not vary
// independently, give samples = 0.
YawRateAgreement CompareYawRates(const sensors::ImuSamples& imu,
                                 const ScalarSeries& wheel_speed_m_s,
                                 const ScalarSeries& wheel_yaw_rate_rad_s, double offset_s,
                                 const Eigen::Vector3d& up_I);

// ---- GNSS against the IMU.

struct GnssImuOffsetOptions {
  SeriesOffsetOptions series;
  // The GNSS speed is the horizontal distance between fixes at least this far apart over
  // their time difference (centred on their midpoint): single-epoch differences of a slow
  // platform are mostly position noise. The wheel speed is averaged over the same window.
  double speed_baseline_s = 1.0;
  double min_speed_std_m_s = 0.05;
};

// The GNSS receiver's offset t_imu = t_gnss + offset_s, from the track's horizontal speed
// against the wheel speed already on the IMU clock (Shifted(wheel_speed, wheel offset)). The
// wheel speed's scale does not matter; its sign is ignored (the track gives a magnitude).
SeriesOffsetEstimate EstimateGnssImuOffset(const sensors::GnssFixes& fixes,
                                           const ScalarSeries& wheel_speed_on_imu_clock_m_s,
                                           const GnssImuOffsetOptions& options = {});

// The horizontal speed of the GNSS track (see GnssImuOffsetOptions::speed_baseline_s), each
// the median of it and its two neighbours on either side (a multipath fix's spikes dropped).
ScalarSeries GnssHorizontalSpeed(const sensors::GnssFixes& fixes, double baseline_s);

}  // namespace estimation
}  // namespace autocal
