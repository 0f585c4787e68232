#pragma once

// Sensor descriptions that sensors.yaml carries besides the calibration.

#include <cmath>
#include <optional>
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
  // A dropout: two samples farther apart than max_sample_interval_s leave the signal between
  // them unknown, and the preintegration reads it as the line between them. Over such a step it
  // adds a rate and a specific force off that line by these sigmas (per axis, the same over the
  // whole step) to the white noise (docs/factors.md, Eq. F5b). 0: no step is a dropout (the
  // noise alone, as for a sensor's regular stream); pipeline::ImuNoiseFromData sets them from
  // the log.
  double max_sample_interval_s = 0.0;
  double dropout_gyro_sigma_rad_s = 0.0;
  double dropout_accel_sigma_m_s2 = 0.0;

  // 1-sigma of one gyro sample's white noise (rad/s) when sampled at sample_rate_hz.
  double GyroSampleSigmaRadS(double sample_rate_hz) const {
    return gyroscope_noise_density * std::sqrt(sample_rate_hz);
  }
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

// The form in which a vehicle reports its wheels (datasets/README.md, "Wheel forms"); it names
// the dataset file and the calibration blocks the wheels determine.
enum class WheelForm {
  kAngularRates,  // wheel.csv: rear-wheel rates in rad/s; radii and track width
  kLinearSpeeds,  // wheel_speed.csv: rear-wheel speeds in m/s; speed scales and track width
  kSpeedYawRate,  // odometry.csv: body speed and yaw rate; speed scale, effective track
};

// "angular_rates", "linear_speeds", "speed_yaw_rate": the sensors.yaml spelling.
const char* WheelFormName(WheelForm form);
// The form spelled `name`, false when there is none.
bool ParseWheelForm(const std::string& name, WheelForm* form);
// The dataset file that carries the form: "wheel.csv", "wheel_speed.csv", "odometry.csv".
const char* WheelFormFile(WheelForm form);

struct WheelConfig {
  WheelForm form = WheelForm::kAngularRates;
  double rate_hz = 100.0;
  double noise_rad_s = 0.02;  // angular_rates: 1-sigma of each wheel rate
  // linear_speeds: 1-sigma of each wheel speed; speed_yaw_rate: 1-sigma of the speed.
  double noise_m_s = 0.02;
  double yaw_rate_noise_rad_s = 0.02;  // speed_yaw_rate: 1-sigma of the yaw rate
  // speed_yaw_rate: the wheel separation b_ctrl the controller divides by to report its yaw
  // rate; unset means the nominal effective track (the nominal yaw-rate scale is then 1).
  std::optional<double> controller_track_m;
  // The rear axle's sideways slip, the error of the zero-lateral-speed row
  // (docs/keyframe_factors.md, Eq. K6c): its 1-sigma driving straight, and the cornering
  // compliance c, the slip angle per lateral acceleration, whose slip c v |v omega| in a turn
  // adds to the straight one in quadrature.
  // The defaults hold for any platform (a skid steer slides sideways in every turn); a road
  // car states its own.
  double lateral_slip_sigma_m_s = 0.05;
  double cornering_compliance_rad_per_m_s2 = 0.0;
};

struct GnssConfig {
  double rate_hz = 10.0;
};

}  // namespace sensors
}  // namespace autocal
