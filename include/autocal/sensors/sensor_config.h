#pragma once

// Sensor descriptions that sensors.yaml carries besides the calibration.

#include <string>

namespace autocal {
namespace sensors {

// Continuous-time IMU noise, named as in Kalibr's imu.yaml so values can be pasted.
// Defaults: EuRoC-class MEMS (ADIS16448 as published with EuRoC).
struct ImuNoise {
  double gyroscope_noise_density = 1.6968e-4;      // rad/s/sqrt(Hz)
  double gyroscope_random_walk = 1.9393e-5;        // rad/s^2/sqrt(Hz)
  double accelerometer_noise_density = 2.0000e-3;  // m/s^2/sqrt(Hz)
  double accelerometer_random_walk = 3.0000e-3;    // m/s^3/sqrt(Hz)
  double update_rate_hz = 200.0;                   // Hz
};

struct ImuConfig {
  ImuNoise noise;
  double gravity_m_s2 = 9.80665;
};

// Spinning multi-beam LiDAR.
struct LidarConfig {
  int num_beams = 32;
  double rate_hz = 10.0;
  double min_elevation_deg = -25.0;
  double max_elevation_deg = 15.0;
  double azimuth_resolution_deg = 0.4;
  double min_range_m = 1.0;
  double max_range_m = 100.0;
  double range_noise_m = 0.02;  // 1-sigma
};

struct WheelConfig {
  double rate_hz = 100.0;
  double noise_rad_s = 0.02;  // 1-sigma of each wheel rate
};

struct GnssConfig {
  double rate_hz = 10.0;
};

}  // namespace sensors
}  // namespace autocal
