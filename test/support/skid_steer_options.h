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

// The same with the real robot's vibration: the IMU's white noise 30 times the bench densities,
// its bias random walks at the bench values (test1.bag's samples scatter so).
inline sim::SimulationOptions VibratingSkidSteerOdometryOptions(double duration_s, uint64_t seed) {
  sim::SimulationOptions options = SkidSteerOdometryOptions(duration_s, seed);
  options.imu.noise_scale = 30.0;
  options.imu.random_walk_scale = 1.0;
  return options;
}

}  // namespace test
}  // namespace autocal
