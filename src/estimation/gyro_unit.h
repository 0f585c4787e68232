#pragma once

// A gyroscope logged in deg/s instead of rad/s, recognized at rest (docs/initialization.md,
// "Still start"): while the accelerometer is steady the vehicle stands still, and a still
// gyro reads only noise and bias. In deg/s both are 57 times larger, so the still-start test
// fails on the gyro's scatter; read as deg/s (times pi/180) the same samples pass. A steady
// turn, which also fails the test as read, fails on the mean rate, not on the scatter: it is
// not mistaken for a unit slip. Private to the library (io and estimation use it).

#include <cstddef>
#include <optional>

#include "autocal/estimation/initialization.h"
#include "autocal/sensors/measurements.h"

namespace autocal {
namespace estimation {
namespace internal {

struct GyroInDegreesAtRest {
  size_t first_sample = 0;         // the first sample of the still period
  double duration_s = 0.0;         // its length
  double gyro_std_as_read = 0.0;   // largest per-axis standard deviation there, as logged
  double gyro_mean_as_read = 0.0;  // norm of the mean there, as logged
};

// The still period that DetectStillStart(imu, options) finds only with the gyro read as deg/s,
// when the gyro's scatter as logged is what fails there; nullopt when the log has a still
// start as it is, has none either way, or only its mean rate fails.
std::optional<GyroInDegreesAtRest> FindGyroInDegreesAtRest(const sensors::ImuSamples& imu,
                                                           const StillStartOptions& options);

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
