// The IMU noise the calibration uses (pipeline/clock_initialization.h, ImuNoiseFromData):
// sensors.yaml's densities unless the samples scatter at least 1.5 times more (Eq. N1).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "autocal/io/dataset.h"
#include "pipeline/clock_initialization.h"

namespace autocal {
namespace pipeline {
namespace {

// 60 s at 100 Hz, standing still, with white noise of the given densities.
io::Dataset StillLog(double gyro_density, double accel_density) {
  io::Dataset dataset;
  std::mt19937_64 random(5);
  std::normal_distribution<double> normal(0.0, 1.0);
  for (int k = 0; k < 6000; ++k) {
    sensors::ImuSample s;
    s.t_ns = 1'000'000'000 + int64_t{10'000'000} * k;
    for (int i = 0; i < 3; ++i) {
      s.gyro_rad_s(i) = gyro_density * 10.0 * normal(random);
      s.accel_m_s2(i) = (i == 2 ? 9.81 : 0.0) + accel_density * 10.0 * normal(random);
    }
    dataset.imu.push_back(s);
  }
  return dataset;
}

TEST(ImuNoiseFromData, KeepsTheStatedNoiseWhenTheSamplesAgree) {
  const io::Dataset dataset = StillLog(1.7e-4, 2e-3);
  std::vector<std::string> warnings;
  std::optional<io::Dataset> storage;
  const io::Dataset& used = WithImuNoiseFromData(dataset, &storage, &warnings);
  EXPECT_EQ(&used, &dataset);
  EXPECT_FALSE(storage.has_value());
  EXPECT_TRUE(warnings.empty());
}

// A vibrating platform: the accelerometer scatters 20 times the stated density, the gyro
// 1.2 times (under the 1.5 threshold: kept). The random walks stay.
TEST(ImuNoiseFromData, UsesTheMeasuredDensityOfAVibratingImu) {
  const io::Dataset dataset = StillLog(1.2 * 1.7e-4, 20.0 * 2e-3);
  std::vector<std::string> warnings;
  std::optional<io::Dataset> storage;
  const io::Dataset& used = WithImuNoiseFromData(dataset, &storage, &warnings);
  ASSERT_TRUE(storage.has_value());
  EXPECT_EQ(&used, &*storage);
  const sensors::ImuNoise& stated = dataset.sensors.imu.noise;
  const sensors::ImuNoise& noise = used.sensors.imu.noise;
  EXPECT_NEAR(noise.accelerometer_noise_density, 20.0 * 2e-3, 0.05 * 20.0 * 2e-3);
  EXPECT_EQ(noise.gyroscope_noise_density, stated.gyroscope_noise_density);
  EXPECT_EQ(noise.accelerometer_random_walk, stated.accelerometer_random_walk);
  EXPECT_EQ(noise.gyroscope_random_walk, stated.gyroscope_random_walk);
  EXPECT_EQ(used.imu.size(), dataset.imu.size());
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_THAT(warnings[0], ::testing::HasSubstr("IMU accelerometer: its samples scatter"));
  EXPECT_THAT(warnings[0], ::testing::HasSubstr("the IMU factors use the measured density"));
}

}  // namespace
}  // namespace pipeline
}  // namespace autocal
