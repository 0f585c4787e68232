#pragma once

// The urban drive the pipeline suites run on (seed 7, 16 beams: a still start, straight
// driving and a roundabout from 18 s, which the initializer needs), written as a dataset once
// per test program and build (test/support/simulation_cache.h) and shared by its tests, which
// only read it.

#include <cmath>
#include <filesystem>
#include <string>

#include <Eigen/Geometry>

#include "autocal/io/dataset.h"
#include "autocal/sim/simulator.h"
#include "support/simulation_cache.h"

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
  // Any other drive, cached the same way. `name` only documents the caller's drive: the
  // cache tells drives apart by their options.
  SimulatedUrbanDataset(const sim::SimulationOptions& options, const std::string& /*name*/)
      : simulator(options) {
    CachedDatasetEntry entry = CachedDataset(simulator);
    directory = entry.directory;
    summary = entry.summary;
  }
  SimulatedUrbanDataset(const SimulatedUrbanDataset&) = delete;
  SimulatedUrbanDataset& operator=(const SimulatedUrbanDataset&) = delete;

  const sim::Simulator simulator;
  std::string directory;  // shared by the program's tests: read it, never write into it
  sim::SimulationSummary summary;
};

}  // namespace test
}  // namespace autocal
