#pragma once

// The urban drive the pipeline suites run on (seed 7, 16 beams: a still start, straight
// driving and a roundabout from 18 s, which the initializer needs), simulated and written as a
// dataset once per test process. ctest runs each test in its own process, in parallel, so
// each writes its own copy (the directory name carries the process id) and removes it.

#include <cmath>
#include <filesystem>
#include <string>

#include <unistd.h>

#include <Eigen/Geometry>

#include "autocal/io/dataset.h"
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

// The bad guess: the nominal LiDAR rotation turned by 20 deg, its translation moved
// by 0.3 m and the time offset by 40 ms. A guess that bad comes with no stated uncertainty
// (the simulator states 1.5 deg, 3 cm and 4 ms), so the spoiled blocks' sigmas are dropped.
inline void SpoilNominalGuess(io::SensorsConfig* config) {
  sensors::Calibration& nominal = config->nominal_calibration;
  const Eigen::Vector3d axis = Eigen::Vector3d(1.0, -2.0, 3.0).normalized();
  nominal.q_I_L =
      (nominal.q_I_L * Eigen::Quaterniond(Eigen::AngleAxisd(20.0 * M_PI / 180.0, axis)))
          .normalized();
  nominal.p_I_L += 0.3 * Eigen::Vector3d(1.0, -1.0, 1.0).normalized();
  nominal.time_offset_lidar_imu_s += 0.040;
  config->nominal_uncertainty.T_I_L = io::PoseBlockInfo();
  config->nominal_uncertainty.time_offset_lidar_imu_s = io::ScalarBlockInfo();
}

struct SimulatedUrbanDataset {
  SimulatedUrbanDataset(double duration_s, const std::string& name)
      : SimulatedUrbanDataset(UrbanDriveOptions(duration_s), name) {}
  // Any other drive, written and removed the same way.
  SimulatedUrbanDataset(const sim::SimulationOptions& options, const std::string& name)
      : simulator(options),
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
