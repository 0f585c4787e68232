#pragma once

// Plausibility checks that catch unit mistakes and corrupt rows in an IMU log
// (datasets/README.md).

#include "autocal/common/units.h"

namespace autocal {
namespace io {

// Unit checks over a whole imu.csv, catching the two common export mistakes.
struct ImuPlausibilityOptions {
  bool enabled = true;
  // A car turns at most ~1 rad/s (a 5 m radius at 18 km/h) and rolls/pitches far slower,
  // so in rad/s the 99th percentile of |omega| stays well below 3 rad/s. The same drive
  // logged in deg/s has 57x larger numbers: as soon as more than 1% of the log turns faster
  // than 3 deg/s (any corner), the percentile passes the limit. The percentile, not the
  // maximum, keeps a few spikes (a pothole) from tripping the check. A log that never
  // turns cannot be told apart and passes.
  double gyro_percentile = 0.99;
  double max_gyro_percentile_rad_s = 3.0;
  // A log that never turns fast is told apart at rest (estimation::DetectStillStart's default
  // thresholds): where the accelerometer is steady for a second in the first 30 s, a still
  // gyro reads noise and bias only. Logged in deg/s both are 57x larger, so the gyro's scatter
  // fails the still test as logged and passes it read as deg/s. A steady turn fails on its mean
  // rate, not its scatter, and is not taken for a unit slip; neither is a gyro whose scatter
  // there is within max_still_noise_ratio of the noise sensors.yaml states (a noisy gyro in
  // rad/s): in deg/s it is about 57 times that.
  bool check_gyro_unit_at_rest = true;
  double max_still_noise_ratio = 10.0;
  // The stated gyro noise: its per-sample standard deviation is the density times
  // sqrt(update rate). ReadDataset copies both from sensors.yaml.
  double gyroscope_noise_density = 1.6968e-4;  // rad/s/sqrt(Hz)
  double update_rate_hz = 200.0;
  // The accelerometer measures specific force: over a log its norm is close to g (the
  // vehicle's own accelerations average out). A median below this fraction of g means gravity
  // was removed (or the unit is g); above max_median_accel_g the unit is wrong. The median,
  // not the mean, keeps a few corrupt rows from passing for a unit.
  double min_median_accel_g = 0.5;
  double max_median_accel_g = 2.0;
  double gravity_m_s2 = 9.80665;
  // No IMU reads beyond these full-scale ranges (the widest common MEMS parts: 200 g shock
  // accelerometers, 4000 deg/s gyroscopes): a row beyond them is corrupt, not a measurement,
  // and is refused at its line.
  double max_sample_accel_g = 200.0;
  double max_sample_gyro_rad_s = 4000.0 * kDegToRad;
};

}  // namespace io
}  // namespace autocal
