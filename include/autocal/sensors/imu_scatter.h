#pragma once

// How much an IMU's samples scatter from one to the next, as a white-noise density
// (docs/calibration.md, "IMU noise from the data").
//
// A datasheet's noise density describes the sensor on a bench. On a vehicle the samples
// also carry vibration (engine, rough ground, the mount's resonance) that the IMU factors
// cannot model and must treat as noise: on a skid-steer robot on grass the accelerometer
// scatters about 40 times its bench density. The second difference of consecutive samples
// removes the motion (up to its second derivative over two intervals, which is small) and
// keeps the noise, whose variance it multiplies by 1 + 4 + 1 = 6:
//   sigma_axis   = MadSigma(x_{k+1} - 2 x_k + x_{k-1}) / sqrt(6)   (per axis, robust to
//                                                                   manoeuvres)
//   density_axis = sigma_axis / sqrt(f),   f = 1 / median interval                     (Eq. N1)
// and the sensor's density is the RMS over its three axes (the factors' noise is isotropic).
// A first difference would leave the motion's change over one interval: at 25 Hz a car's
// 1 m/s^3 of jerk alone would read as three times a datasheet's accelerometer density.

#include <Eigen/Core>
#include <cstddef>

#include "autocal/sensors/measurements.h"

namespace autocal {
namespace sensors {

struct ImuScatter {
  size_t differences = 0;  // consecutive pairs used
  double rate_hz = 0.0;    // 1 / mean interval, outages left out (MeasureTiming)
  Eigen::Vector3d gyro_density = Eigen::Vector3d::Zero();   // rad/s/sqrt(Hz) per IMU axis
  Eigen::Vector3d accel_density = Eigen::Vector3d::Zero();  // m/s^2/sqrt(Hz) per IMU axis

  double gyroscope_noise_density() const;      // RMS over the axes
  double accelerometer_noise_density() const;  // RMS over the axes
};

// Eq. N1 over `imu` (strictly increasing stamps). Throws autocal::Error for fewer than
// three samples or a stamp that does not follow its predecessor.
ImuScatter MeasureImuScatter(const ImuSamples& imu);

}  // namespace sensors
}  // namespace autocal
