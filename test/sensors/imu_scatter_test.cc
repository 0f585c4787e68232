#include "autocal/sensors/imu_scatter.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "autocal/common/error.h"

namespace autocal {
namespace sensors {
namespace {

// A slow drive (turns and speed changes at 0.1-0.3 Hz, a step of 2 m/s^2 when braking hard)
// sampled at rate_hz with white noise of the given densities on every axis.
ImuSamples Drive(double rate_hz, double duration_s, double gyro_density, double accel_density,
                 uint64_t seed) {
  std::mt19937_64 random(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  const double gyro_sigma = gyro_density * std::sqrt(rate_hz);
  const double accel_sigma = accel_density * std::sqrt(rate_hz);
  ImuSamples imu;
  for (int64_t k = 0; static_cast<double>(k) / rate_hz < duration_s; ++k) {
    const double t = static_cast<double>(k) / rate_hz;
    ImuSample s;
    s.t_ns = 1'000'000'000 + static_cast<int64_t>(std::llround(t * 1e9));
    s.gyro_rad_s = Eigen::Vector3d(0.02 * std::sin(0.6 * t), 0.01 * std::cos(0.9 * t),
                                   0.5 * std::sin(0.4 * t));
    s.accel_m_s2 = Eigen::Vector3d(1.5 * std::sin(0.7 * t) - (t > 30.0 && t < 31.0 ? 2.0 : 0.0),
                                   0.5 * std::sin(0.4 * t), 9.81);
    for (int i = 0; i < 3; ++i) {
      s.gyro_rad_s(i) += gyro_sigma * normal(random);
      s.accel_m_s2(i) += accel_sigma * normal(random);
    }
    imu.push_back(s);
  }
  return imu;
}

// Eq. N1 recovers the white-noise density under the motion, at a datasheet's noise and at a
// vibrating robot's, from 25 Hz to 1 kHz: within 3 % (about four standard errors of the MAD
// over these sample counts).
TEST(MeasureImuScatter, RecoversTheWhiteNoiseDensityUnderSlowMotion) {
  for (const double rate_hz : {25.0, 30.0, 200.0, 1000.0}) {
    for (const double scale : {1.0, 40.0}) {
      const double gyro = 1.7e-4 * scale, accel = 2e-3 * scale;
      const ImuScatter s = MeasureImuScatter(Drive(rate_hz, 400.0, gyro, accel, 7));
      EXPECT_NEAR(s.rate_hz, rate_hz, 1e-6 * rate_hz);
      EXPECT_NEAR(s.gyroscope_noise_density(), gyro, 0.03 * gyro) << rate_hz << " Hz x" << scale;
      EXPECT_NEAR(s.accelerometer_noise_density(), accel, 0.03 * accel)
          << rate_hz << " Hz x" << scale;
      for (int i = 0; i < 3; ++i) {
        EXPECT_NEAR(s.accel_density(i), accel, 0.05 * accel) << rate_hz << " Hz axis " << i;
      }
    }
  }
}

// A driver that stamps its samples in bursts of four (0.1 ms apart) at 200 Hz: the density is
// that of the samples' own rate. The median interval read 10 kHz before, and the densities
// sqrt(50) times too small.
TEST(MeasureImuScatter, TakesTheRateOfBurstyStamps) {
  ImuSamples imu = Drive(200.0, 400.0, 1.7e-4, 2e-3, 7);
  for (size_t k = 0; k < imu.size(); ++k) {
    imu[k].t_ns = imu[k - k % 4].t_ns + static_cast<int64_t>(k % 4) * 100'000;
  }
  const ImuScatter s = MeasureImuScatter(imu);
  EXPECT_NEAR(s.rate_hz, 200.0, 1.0);
  EXPECT_NEAR(s.gyroscope_noise_density(), 1.7e-4, 0.03 * 1.7e-4);
  EXPECT_NEAR(s.accelerometer_noise_density(), 2e-3, 0.03 * 2e-3);
}

// The motion alone is not taken for noise: without noise the scatter of the drive is under a
// tenth of a datasheet's density even at 25 Hz (it adds in quadrature: under 0.5 %).
TEST(MeasureImuScatter, MotionAloneScattersFarLessThanNoise) {
  for (const double rate_hz : {25.0, 200.0}) {
    const ImuScatter s = MeasureImuScatter(Drive(rate_hz, 100.0, 0.0, 0.0, 1));
    EXPECT_LT(s.gyroscope_noise_density(), 0.1 * 1.7e-4) << rate_hz;
    EXPECT_LT(s.accelerometer_noise_density(), 0.1 * 2e-3) << rate_hz;
  }
}

TEST(MeasureImuScatter, RejectsTooFewOrUnorderedSamples) {
  ImuSamples imu = Drive(100.0, 1.0, 1e-3, 1e-2, 3);
  EXPECT_THROW(MeasureImuScatter(ImuSamples(imu.begin(), imu.begin() + 2)), Error);
  imu[10].t_ns = imu[9].t_ns;
  EXPECT_THROW(MeasureImuScatter(imu), Error);
}

}  // namespace
}  // namespace sensors
}  // namespace autocal
