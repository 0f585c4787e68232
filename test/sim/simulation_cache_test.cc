// The fixture cache of test/support/simulation_cache.h: what it loads equals what the
// simulator makes, bit for bit, and its key tells apart options that differ in one field.

#include "support/simulation_cache.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <sstream>
#include <string>

#include "autocal/io/dataset.h"
#include "autocal/sim/simulator.h"
#include "support/test_paths.h"

namespace autocal {
namespace {

// A short drive with every sensor on (LiDAR with few beams, to keep it quick).
sim::SimulationOptions ShortDrive() {
  sim::SimulationOptions options;
  options.duration_s = 2.0;
  options.seed = 11;
  options.lidar.config.num_beams = 4;
  return options;
}

std::string Bytes(sim::SimulatedLog log) {
  test::simulation_cache::Writer writer;
  writer(log);
  return writer.bytes();
}

std::string Bytes(sim::SimulationSummary summary) {
  test::simulation_cache::Writer writer;
  writer(summary);
  return writer.bytes();
}

TEST(SimulationCache, LoadsTheSimulatedLogBitForBit) {
  const sim::Simulator simulator(ShortDrive());
  const sim::SimulatedLog simulated = sim::Simulate(simulator);
  ASSERT_FALSE(simulated.sweeps.empty());
  ASSERT_FALSE(simulated.gnss.fixes.empty());
  const std::string expected = Bytes(simulated);
  // The first call may simulate (a miss), the second loads the entry.
  EXPECT_EQ(Bytes(test::CachedSimulatedLog(simulator)), expected);
  const sim::SimulatedLog loaded = test::CachedSimulatedLog(simulator);
  EXPECT_EQ(Bytes(loaded), expected);
  // The byte comparison covers the values; these check that the reader rebuilt the shapes.
  ASSERT_EQ(loaded.sweeps.size(), simulated.sweeps.size());
  EXPECT_EQ(loaded.sweeps[0].cloud.points, simulated.sweeps[0].cloud.points);
  EXPECT_EQ(loaded.gnss.is_outlier, simulated.gnss.is_outlier);
  EXPECT_EQ(loaded.imu.truth.back().T_W_I.q.coeffs(), simulated.imu.truth.back().T_W_I.q.coeffs());
}

TEST(SimulationCache, SharesOneDatasetDirectoryWithTheWrittenFiles) {
  const sim::Simulator simulator(ShortDrive());
  const std::string fresh = test::OutputDir("fresh").string();
  std::filesystem::remove_all(fresh);
  const sim::SimulationSummary summary = sim::WriteDataset(simulator, fresh);
  const test::CachedDatasetEntry first = test::CachedDataset(simulator);
  const test::CachedDatasetEntry second = test::CachedDataset(simulator);
  EXPECT_EQ(first.directory, second.directory);
  EXPECT_EQ(Bytes(first.summary), Bytes(summary));
  EXPECT_EQ(Bytes(second.summary), Bytes(summary));
  for (const auto& file : std::filesystem::recursive_directory_iterator(fresh)) {
    if (!file.is_regular_file()) continue;
    const std::filesystem::path relative = std::filesystem::relative(file.path(), fresh);
    EXPECT_EQ(test::simulation_cache::ReadFile(std::filesystem::path(first.directory) / relative),
              test::simulation_cache::ReadFile(file.path()))
        << relative;
  }
  EXPECT_EQ(io::ReadDataset(first.directory).imu.size(), io::ReadDataset(fresh).imu.size());
}

TEST(SimulationCache, KeyChangesWithAnyOption) {
  const sim::SimulationOptions base = ShortDrive();
  const std::string key = test::simulation_cache::OptionsKey(base);
  EXPECT_EQ(test::simulation_cache::OptionsKey(base), key);
  sim::SimulationOptions seed = base;
  seed.seed += 1;
  EXPECT_NE(test::simulation_cache::OptionsKey(seed), key);
  EXPECT_NE(test::simulation_cache::OptionsKey(base.WithoutNoise()), key);
  sim::SimulationOptions origin = base;
  origin.gnss.origin_alt_m += 1e-9;
  EXPECT_NE(test::simulation_cache::OptionsKey(origin), key);
  sim::SimulationOptions lever_arm = base;
  lever_arm.true_calibration.p_I_A.z() += 0.01;
  EXPECT_NE(test::simulation_cache::OptionsKey(lever_arm), key);
}

TEST(SimulationCache, MakesAValueOnceAndLoadsItBitForBit) {
  const sim::SimulatedLog log = sim::Simulate(sim::Simulator(ShortDrive()));
  const std::string name = "short_drive_sweeps";
  int made = 0;
  const auto make = [&] {
    ++made;
    return log.sweeps;
  };
  // The first call makes the value unless an earlier run of this build did; the second loads it.
  const auto first = test::CachedValue<std::vector<lidar::LidarSweep>>(name, make);
  EXPECT_LE(made, 1);
  const int made_before_second = made;
  const auto second = test::CachedValue<std::vector<lidar::LidarSweep>>(name, make);
  EXPECT_EQ(made, made_before_second);
  ASSERT_EQ(second.size(), log.sweeps.size());
  for (size_t i = 0; i < log.sweeps.size(); ++i) {
    EXPECT_EQ(first[i].t_ns, log.sweeps[i].t_ns);
    EXPECT_EQ(second[i].cloud.points, log.sweeps[i].cloud.points);
    EXPECT_EQ(second[i].cloud.time_s, log.sweeps[i].cloud.time_s);
    EXPECT_EQ(second[i].cloud.intensity, log.sweeps[i].cloud.intensity);
  }
}

TEST(SimulationCache, RefusesATruncatedEntry) {
  sim::SimulatedLog log = sim::Simulate(sim::Simulator(ShortDrive()));
  std::string bytes = Bytes(log);
  bytes.resize(bytes.size() / 2);
  std::istringstream in(bytes);
  test::simulation_cache::Reader reader(in, bytes.size());
  sim::SimulatedLog loaded;
  EXPECT_THROW(reader(loaded), Error);
}

}  // namespace
}  // namespace autocal
