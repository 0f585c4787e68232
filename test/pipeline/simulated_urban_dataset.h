#pragma once

// The urban drive the pipeline suites run on (seed 7, 16 beams: a still start, straight
// driving and a roundabout from 18 s, which the initializer needs), written as a dataset once
// per test program and build (test/support/simulation_cache.h) and shared by its tests, which
// only read it; or, for a one-off drive, written privately and removed.

#include <unistd.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <string>

#include "autocal/common/units.h"
#include "autocal/io/dataset.h"
#include "autocal/io/problem_yaml.h"
#include "autocal/sim/simulator.h"
#include "sim/sim_test_util.h"
#include "support/simulation_cache.h"
#include "support/test_paths.h"

namespace autocal {
namespace test {

// A problem file shipped in problems/, e.g. "imu_wheel_gnss.yaml".
inline io::Problem ShippedProblem(const std::string& file) {
  return io::ReadProblemYaml(
      (std::filesystem::path(AUTOCAL_SOURCE_DIR) / "problems" / file).string());
}

inline sim::SimulationOptions UrbanDriveOptions(double duration_s) {
  sim::SimulationOptions options;
  options.scenario = sim::ScenarioType::kUrban;
  options.duration_s = duration_s;
  options.seed = 7;
  options.lidar.config.num_beams = 16;
  return options;
}

// The urban drive with every sweep stamped when it ends, its points at negative times
// (sim::LidarSimOptions::stamp_at_end), as some drivers write them.
inline sim::SimulationOptions EndStampedUrbanDriveOptions(double duration_s) {
  sim::SimulationOptions options = UrbanDriveOptions(duration_s);
  options.lidar.stamp_at_end = true;
  return options;
}

// A highway drive (about 120 km/h, no turns, traffic around the car) with a VLP-16's beams
// (sim::test::SmallLog).
inline sim::SimulationOptions HighwayDriveOptions(double duration_s, uint64_t seed) {
  return sim::test::SmallLog(sim::ScenarioType::kHighway, duration_s, seed);
}

// Wheels reported as the controller's twist (odometry.csv) that reports 3 % too much speed
// and divides by the physical track of a vehicle whose effective track is 1.2 times that
// (k_v 0.97, b_ctrl = the nominal 1.60 m, b_eff 1.92 m), with the noise the default encoders
// (0.02 rad/s per wheel, r = 0.33 m, b = 1.6 m) give through the controller's formulas:
// r 0.02 / sqrt(2) m/s and r 0.02 sqrt(2) / b rad/s.
inline void UseOdometryTwist(sim::SimulationOptions* options) {
  options->wheel.config.form = sensors::WheelForm::kSpeedYawRate;
  options->true_calibration.odometry_speed_scale = 0.97;
  options->true_calibration.effective_track_m = 1.92;
  options->wheel.config.noise_m_s = 0.0047;
  options->wheel.config.yaw_rate_noise_rad_s = 0.0058;
}

// The bad guess: the nominal LiDAR rotation turned by 20 deg, its translation moved
// by 0.3 m and the time offset by 40 ms. A guess that bad comes with no stated uncertainty
// (the simulator states 1.5 deg, 3 cm and 4 ms), so the spoiled blocks' sigmas are dropped.
inline void SpoilNominalGuess(io::SensorsConfig* config) {
  sensors::Calibration& nominal = config->nominal_calibration;
  const Eigen::Vector3d axis = Eigen::Vector3d(1.0, -2.0, 3.0).normalized();
  nominal.q_I_L =
      (nominal.q_I_L * Eigen::Quaterniond(Eigen::AngleAxisd(20.0 * kDegToRad, axis))).normalized();
  nominal.p_I_L += 0.3 * Eigen::Vector3d(1.0, -1.0, 1.0).normalized();
  nominal.time_offset_lidar_imu_s += 0.040;
  config->nominal_uncertainty.T_I_L = io::PoseBlockInfo();
  config->nominal_uncertainty.time_offset_lidar_imu_s = io::ScalarBlockInfo();
}

// A wrong nominal lever arm stated with confidence: moved dx_m along x and stated to sigma_m on
// every axis, a prior the drive contradicts when dx_m is many sigma_m (the tests of the
// plausibility refusal).
inline void MisstateNominalLeverArm(io::SensorsConfig* config, double dx_m, double sigma_m) {
  config->nominal_calibration.p_I_A.x() += dx_m;
  io::VectorBlockInfo stated;
  stated.sigma = Eigen::Vector3d::Constant(sigma_m);
  config->nominal_uncertainty.p_I_A_m = stated;
}

// Where the dataset lives: kCached, once per test program and build, shared by its tests
// (for fixtures: ctest runs each test in its own process); kPrivate, a copy of this object's
// own, removed with it (for a long drive simulated once, whose copy would only take disk
// space in the cache).
enum class DatasetStorage { kCached, kPrivate };

struct SimulatedUrbanDataset {
  SimulatedUrbanDataset(double duration_s, const std::string& name)
      : SimulatedUrbanDataset(UrbanDriveOptions(duration_s), name) {}
  // Any other drive. `name` names a private copy; the cache tells drives apart by their
  // options.
  SimulatedUrbanDataset(const sim::SimulationOptions& options, const std::string& name,
                        DatasetStorage storage = DatasetStorage::kCached)
      : simulator(options), storage_(storage) {
    if (storage == DatasetStorage::kPrivate) {
      directory = OutputDir(name + "_" + std::to_string(static_cast<long>(getpid()))).string();
      std::filesystem::remove_all(directory);
      summary = sim::WriteDataset(simulator, directory);
      return;
    }
    CachedDatasetEntry entry = CachedDataset(simulator);
    directory = entry.directory;
    summary = entry.summary;
  }
  ~SimulatedUrbanDataset() {
    if (storage_ == DatasetStorage::kPrivate) std::filesystem::remove_all(directory);
  }
  SimulatedUrbanDataset(const SimulatedUrbanDataset&) = delete;
  SimulatedUrbanDataset& operator=(const SimulatedUrbanDataset&) = delete;

  const sim::Simulator simulator;
  std::string directory;  // cached: shared by the program's tests, read it and never write
  sim::SimulationSummary summary;

 private:
  DatasetStorage storage_;
};

}  // namespace test
}  // namespace autocal
