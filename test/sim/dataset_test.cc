// A simulated dataset written to disk reads back with io::ReadDataset and carries the same
// measurements, truth and calibrations as the log generated in memory.

#include "autocal/io/dataset.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "autocal/common/error.h"
#include "autocal/sim/simulator.h"
#include "sim/sim_test_util.h"
#include "support/test_paths.h"

namespace autocal {
namespace sim {
namespace {

class DatasetTest : public ::testing::TestWithParam<ScenarioType> {};

TEST_P(DatasetTest, WrittenDatasetReadsBackWithTheSameContent) {
  SimulationOptions options = test::SmallLog(GetParam(), 4.0);
  options.lidar.config.azimuth_resolution_deg = 1.0;  // small files
  const Simulator simulator(options);
  const std::string directory =
      (autocal::test::OutputDir("sim_dataset") / test::Name(GetParam())).string();
  const SimulationSummary summary = WriteDataset(simulator, directory);
  const SimulatedLog log = Simulate(simulator);

  const io::Dataset dataset = io::ReadDataset(directory);
  ASSERT_EQ(dataset.imu.size(), log.imu.samples.size());
  for (size_t k = 0; k < dataset.imu.size(); k += 97) {
    EXPECT_EQ(dataset.imu[k].t_ns, log.imu.samples[k].t_ns);
    EXPECT_TRUE(dataset.imu[k].accel_m_s2.isApprox(log.imu.samples[k].accel_m_s2, 1e-9))
        << "sample " << k;
    EXPECT_TRUE(dataset.imu[k].gyro_rad_s.isApprox(log.imu.samples[k].gyro_rad_s, 1e-9))
        << "sample " << k;
  }
  ASSERT_EQ(dataset.wheel.size(), log.wheel.size());
  EXPECT_NEAR(dataset.wheel.back().left_rad_s, log.wheel.back().left_rad_s, 1e-9);
  ASSERT_EQ(dataset.gnss.size(), log.gnss.fixes.size());
  EXPECT_NEAR(dataset.gnss.back().lat_deg, log.gnss.fixes.back().lat_deg, 1e-12);
  ASSERT_EQ(dataset.groundtruth_trajectory.size(), log.imu.truth.size());
  EXPECT_LT((dataset.groundtruth_trajectory.back().T_W_I.p - log.imu.truth.back().T_W_I.p).norm(),
            1e-9);

  ASSERT_TRUE(dataset.groundtruth_calibration.has_value());
  const sensors::Calibration& truth = *dataset.groundtruth_calibration;
  EXPECT_NEAR(truth.time_offset_lidar_imu_s, simulator.true_calibration().time_offset_lidar_imu_s,
              1e-12);
  EXPECT_TRUE(truth.p_I_L.isApprox(simulator.true_calibration().p_I_L, 1e-12));
  EXPECT_NEAR(dataset.sensors.nominal_calibration.time_offset_lidar_imu_s,
              simulator.nominal_calibration().time_offset_lidar_imu_s, 1e-12);
  ASSERT_TRUE(dataset.sensors.lidar.has_value());
  EXPECT_EQ(dataset.sensors.lidar->num_beams, 16);

  ASSERT_EQ(dataset.lidar_sweeps.size(), log.sweeps.size());
  ASSERT_EQ(summary.sweeps, static_cast<int64_t>(log.sweeps.size()));
  const size_t k = log.sweeps.size() / 2;
  const lidar::LidarSweep sweep = dataset.LoadSweep(k);
  EXPECT_EQ(sweep.t_ns, log.sweeps[k].t_ns);
  ASSERT_EQ(sweep.cloud.size(), log.sweeps[k].cloud.size());
  // PLY stores float: ~1e-5 m at 100 m, ~1e-8 s.
  EXPECT_LT((sweep.cloud.points - log.sweeps[k].cloud.points).cwiseAbs().maxCoeff(), 1e-4);
  ASSERT_TRUE(sweep.cloud.has_time());
  EXPECT_LT((sweep.cloud.time_s - log.sweeps[k].cloud.time_s).cwiseAbs().maxCoeff(), 1e-7);
}

// The wheels in the other forms: only the form's file, read back as written, and the truth
// of its blocks in groundtruth/calibration.yaml.
TEST(DatasetWheelForms, WritesTheFormsFileAndItsTruth) {
  SimulationOptions options = test::SmallLog(ScenarioType::kUrban, 3.0);
  options.lidar.enabled = false;
  options.true_calibration.odometry_speed_scale = 0.97;
  options.true_calibration.effective_track_m = 1.9;
  options.true_calibration.wheel_speed_scale_right = 1.01;
  for (sensors::WheelForm form :
       {sensors::WheelForm::kLinearSpeeds, sensors::WheelForm::kSpeedYawRate}) {
    options.wheel.config.form = form;
    const Simulator simulator(options);
    const std::string directory =
        (autocal::test::OutputDir("sim_dataset") / sensors::WheelFormName(form)).string();
    WriteDataset(simulator, directory);
    const io::Dataset dataset = io::ReadDataset(directory);
    const WheelLog log = simulator.GenerateWheelLog();
    EXPECT_EQ(dataset.wheel_form(), form);
    EXPECT_TRUE(dataset.wheel.empty());
    ASSERT_EQ(dataset.wheel_sample_count(), log.samples.size());
    if (form == sensors::WheelForm::kLinearSpeeds) {
      EXPECT_NEAR(dataset.wheel_speeds.back().right_m_s,
                  simulator.WheelSpeedsOf(log).back().right_m_s, 1e-12);
    } else {
      EXPECT_NEAR(dataset.odometry.back().yaw_rate_rad_s,
                  simulator.OdometryOf(log).back().yaw_rate_rad_s, 1e-12);
    }
    ASSERT_TRUE(dataset.groundtruth_calibration.has_value());
    EXPECT_EQ(dataset.groundtruth_calibration->odometry_speed_scale, 0.97);
    EXPECT_EQ(dataset.groundtruth_calibration->effective_track_m, 1.9);
    EXPECT_EQ(dataset.groundtruth_calibration->wheel_speed_scale_right, 1.01);
    EXPECT_EQ(dataset.sensors.nominal_calibration.odometry_speed_scale, 1.0);
  }
}

// Sweeps generated on several threads give the same files as on one, byte for byte; a thread
// count below 1 is refused.
TEST(WriteDataset, FilesDoNotDependOnTheThreadCount) {
  SimulationOptions options = test::SmallLog(ScenarioType::kUrban, 4.0);
  options.lidar.config.azimuth_resolution_deg = 1.0;  // small files
  const Simulator simulator(options);
  const std::filesystem::path one = autocal::test::OutputDir("sim_dataset") / "threads_1";
  const std::filesystem::path three = autocal::test::OutputDir("sim_dataset") / "threads_3";
  WriteDataset(simulator, one.string(), 1);
  WriteDataset(simulator, three.string(), 3);
  const auto bytes = [](const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  };
  int compared = 0;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(one)) {
    if (!entry.is_regular_file()) continue;
    const std::filesystem::path relative = std::filesystem::relative(entry.path(), one);
    ASSERT_TRUE(std::filesystem::exists(three / relative)) << relative;
    EXPECT_EQ(bytes(entry.path()), bytes(three / relative)) << relative;
    ++compared;
  }
  EXPECT_GT(compared, simulator.num_sweeps());  // every sweep and the other files
  EXPECT_THROW(
      WriteDataset(simulator, (autocal::test::OutputDir("sim_dataset") / "threads_0").string(), 0),
      Error);
}

INSTANTIATE_TEST_SUITE_P(Scenarios, DatasetTest,
                         ::testing::Values(ScenarioType::kUrban, ScenarioType::kHighway,
                                           ScenarioType::kSkidSteer, ScenarioType::kStraight),
                         [](const auto& info) { return test::Name(info.param); });

}  // namespace
}  // namespace sim
}  // namespace autocal
