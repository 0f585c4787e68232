#pragma once

// Small simulated logs shared by the simulator's physics tests.

#include <string>

#include "autocal/sim/simulator.h"

namespace autocal {
namespace sim {
namespace test {

// A short log of the given scenario with a VLP-16's beams, as `autocal_simulate
// --lidar_beams=16` writes them: 2 deg apart over +-15 deg (the default spread, -25 to 15 deg,
// is the 32-beam sensor's).
inline SimulationOptions SmallLog(ScenarioType scenario, double duration_s = 25.0,
                                  uint64_t seed = 3) {
  SimulationOptions options;
  options.scenario = scenario;
  options.duration_s = duration_s;
  options.seed = seed;
  SetSpinningLidarBeams(16, &options.lidar.config);
  return options;
}

inline std::string Name(ScenarioType scenario) { return ScenarioName(scenario); }

}  // namespace test
}  // namespace sim
}  // namespace autocal
