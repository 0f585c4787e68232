#pragma once

// sensors.yaml: the sensors of a rig, their rates and noise, and the nominal calibration.
//
//   imu:                                # required
//     gyroscope_noise_density: 1.6968e-4      # rad/s/sqrt(Hz)   (Kalibr imu.yaml names)
//     gyroscope_random_walk: 1.9393e-5        # rad/s^2/sqrt(Hz)
//     accelerometer_noise_density: 2.0e-3     # m/s^2/sqrt(Hz)
//     accelerometer_random_walk: 3.0e-3       # m/s^3/sqrt(Hz)
//     update_rate: 200.0                      # Hz
//     gravity_m_s2: 9.80665                   # optional
//     rostopic: /imu0                         # optional, ignored (pasted Kalibr files)
//   lidar: {num_beams, rate_hz, min_elevation_deg, max_elevation_deg,
//           azimuth_resolution_deg, min_range_m, max_range_m, range_noise_m}   # optional
//   wheel: {form, rate_hz, noise_rad_s, noise_m_s, yaw_rate_noise_rad_s,       # optional
//           controller_track_m}   # form: angular_rates (default) | linear_speeds | speed_yaw_rate
//   gnss: {rate_hz}                                                            # optional
//   nominal_calibration: {...}          # optional, the schema of calibration_yaml.h
//
// The five IMU noise keys are required; keys of the optional sections default to the
// sensors/sensor_config.h values. Unknown keys, wrong types and implausible values are
// ParseErrors with file, line and column.

#include <string>

#include "autocal/io/dataset.h"

namespace autocal {
namespace io {

// The range ReadSensorsYaml accepts for a wheel sigma (noise_rad_s, noise_m_s,
// yaw_rate_noise_rad_s), in the field's unit.
constexpr double kMinWheelSigma = 1e-6;
constexpr double kMaxWheelSigma = 100.0;

// The rates ReadSensorsYaml accepts, in Hz.
struct RateRangeHz {
  double min;
  double max;
  bool Contains(double rate_hz) const { return rate_hz >= min && rate_hz <= max; }
};
constexpr RateRangeHz kImuRateRangeHz{1.0, 100000.0};
constexpr RateRangeHz kLidarRateRangeHz{0.1, 1000.0};
constexpr RateRangeHz kWheelRateRangeHz{0.1, 100000.0};
constexpr RateRangeHz kGnssRateRangeHz{0.01, 1000.0};

SensorsConfig ReadSensorsYaml(const std::string& path);
// Writes every field, so that ReadSensorsYaml returns exactly `config`.
void WriteSensorsYaml(const std::string& path, const SensorsConfig& config);

}  // namespace io
}  // namespace autocal
