#pragma once

// An urban drive seen by the IMU and a 16-beam LiDAR alone (the default elevation spread,
// -25 to 15 deg; no wheels, no GNSS), over duration_s from `seed`: the LiDAR-inertial suites'.

#include <cstdint>

#include "autocal/sim/simulator.h"

namespace autocal {
namespace test {

inline sim::SimulationOptions LidarInertialUrbanOptions(double duration_s, uint64_t seed) {
  sim::SimulationOptions options;
  options.scenario = sim::ScenarioType::kUrban;
  options.duration_s = duration_s;
  options.seed = seed;
  options.lidar.config.num_beams = 16;
  options.wheel.enabled = false;
  options.gnss.enabled = false;
  return options;
}

}  // namespace test
}  // namespace autocal
