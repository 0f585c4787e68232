#pragma once

// The slow skid-steer robot of the real-data suites, simulated: sim::SkidSteerRobotOptions
// (up to 1 m/s, IMU 30 Hz, 0.6 m fixes at 2.5 Hz) with its wheels reported as the controller's
// speed and yaw rate (odometry.csv), over duration_s from `seed`.

#include <cstdint>

#include "autocal/sim/simulator.h"

namespace autocal {
namespace test {

inline sim::SimulationOptions SkidSteerOdometryOptions(double duration_s, uint64_t seed) {
  sim::SimulationOptions options = sim::SkidSteerRobotOptions();
  options.duration_s = duration_s;
  options.seed = seed;
  options.wheel.config.form = sensors::WheelForm::kSpeedYawRate;
  return options;
}

}  // namespace test
}  // namespace autocal
