#pragma once

// The urban drive the pipeline suites run on (seed 7, 16 beams: a still start, straight
// driving and a roundabout from 18 s, which the initializer needs), simulated and written as a
// dataset once per test process. ctest runs each test in its own process, in parallel, so
// each writes its own copy (the directory name carries the process id) and removes it.

#include <filesystem>
#include <string>

#include <unistd.h>

#include "autocal/sim/simulator.h"
#include "support/test_paths.h"

namespace autocal {
namespace test {

inline sim::SimulationOptions UrbanDriveOptions(double duration_s) {
  sim::SimulationOptions options;
  options.scenario = sim::ScenarioType::kUrban;
  options.duration_s = duration_s;
  options.seed = 7;
  options.lidar.config.num_beams = 16;
  return options;
}

struct SimulatedUrbanDataset {
  SimulatedUrbanDataset(double duration_s, const std::string& name)
      : simulator(UrbanDriveOptions(duration_s)),
        directory(OutputDir(name + "_" + std::to_string(static_cast<long>(getpid()))).string()) {
    std::filesystem::remove_all(directory);
    summary = sim::WriteDataset(simulator, directory);
  }
  ~SimulatedUrbanDataset() { std::filesystem::remove_all(directory); }
  SimulatedUrbanDataset(const SimulatedUrbanDataset&) = delete;
  SimulatedUrbanDataset& operator=(const SimulatedUrbanDataset&) = delete;

  const sim::Simulator simulator;
  const std::string directory;
  sim::SimulationSummary summary;
};

}  // namespace test
}  // namespace autocal
