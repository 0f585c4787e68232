// Is the reported uncertainty true where the drive is weak? On a straight drive the vehicle
// frame's pitch (q_I_V), the IMU's tilt and the accelerometer bias trade against each other:
// only the speed changes separate them. The offline calibration without the LiDAR
// (problems/imu_wheel_gnss.yaml) of simulated straight drives (the CAN-bus car: a 104 Hz
// phone-grade IMU mounted z-down, wheels at 83 Hz, GNSS at 10 Hz; 60 s, one heading, speed
// changes and a stop), each with accelerometer turn-on biases of 0.05 or 0.1 m/s^2 per axis
// (1-sigma), is compared with its truth. Per component, z^2 = e^2 / sigma^2 averaged over the
// drives (NEES) must lie in the two-sided 95 % band of chi^2(n) / n for its n drives, separately
// for the drives that report it observable and those that keep it (their estimate with its
// posterior sigma, not reported observable). A held direction (set to its nominal value and
// reported with its prior sigma) must hold the truth within the two-sided 95 % bound for all
// held directions together (Bonferroni). The mount's roll and pitch priors carry gravity's up
// axis (docs/calibration.md, Eq. C4). The sensor clocks are exact here (the wheel bursts
// and the receiver's late stamps are another subject). About 30 s on one core.
// Figures: docs/calibration.md, "Straight drives".
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "autocal/io/dataset.h"
#include "autocal/io/problem_yaml.h"
#include "autocal/pipeline/offline_calibration.h"
#include "autocal/sim/simulator.h"
#include "support/consistency.h"
#include "support/test_paths.h"

namespace autocal {
namespace {

constexpr int kSeeds = 20;

// The straight drive of seed `seed` and its dataset, in memory.
struct Drive {
  sim::Simulator simulator;
  io::Dataset dataset;
};

sim::SimulationOptions StraightDriveOptions(int seed) {
  sim::SimulationOptions options = sim::CanBusCarOptions();
  options.seed = static_cast<uint64_t>(seed);
  options.imu.initial_accel_bias_sigma_m_s2 = seed % 2 == 0 ? 0.1 : 0.05;
  options.wheel.burst_size = 1;
  options.gnss.time_offset_gnss_imu_s = 0.0;
  return options;
}

Drive SimulateDrive(int seed) {
  Drive drive{sim::Simulator(StraightDriveOptions(seed)), {}};
  const sim::SimulatedLog log = sim::Simulate(drive.simulator);
  drive.dataset.directory = "straight drive, seed " + std::to_string(seed);
  drive.dataset.sensors = drive.simulator.sensors_config();
  drive.dataset.imu = log.imu.samples;
  drive.dataset.wheel = log.wheel;
  drive.dataset.gnss = log.gnss.fixes;
  return drive;
}

TEST(StraightDriveConsistency, NormalizedErrorsPerComponentMatchTheReportedSigmas) {
  const io::Problem problem = io::ReadProblemYaml(
      (std::filesystem::path(AUTOCAL_SOURCE_DIR) / "problems" / "imu_wheel_gnss.yaml").string());
  test::ConsistencyComponents components;
  int calibrated = 0;
  for (int seed = 1; seed <= kSeeds; ++seed) {
    const Drive drive = SimulateDrive(seed);
    if (test::CalibrateAndAddDrive(drive.dataset, problem, drive.simulator.true_calibration(), seed,
                                   &components)) {
      ++calibrated;
    }
  }
  ASSERT_GE(calibrated, kSeeds * 3 / 4) << "too few drives calibrated for a consistency statement";

  test::ExpectConsistent(components);
}

}  // namespace
}  // namespace autocal
