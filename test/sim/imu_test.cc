// The simulated IMU is the exact derivative of the ground truth: compared with finite
// differences of the written trajectory (noise off), and with the stated noise model (noise on).

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "autocal/common/time.h"
#include "autocal/geometry/so3.h"
#include "autocal/sim/simulator.h"
#include "sim/sim_test_util.h"

namespace autocal {
namespace sim {
namespace {

class ImuTest : public ::testing::TestWithParam<ScenarioType> {};

// Specific force and body rate by central differences of the truth at sample k.
struct FiniteDifference {
  Eigen::Vector3d accel_m_s2;
  Eigen::Vector3d gyro_rad_s;
  Eigen::Vector3d velocity_m_s;
};

FiniteDifference Differentiate(const io::Trajectory& truth, size_t k, double gravity) {
  const double dt = NsToSeconds(truth[k + 1].t_ns - truth[k].t_ns);
  const geometry::Pose3d& prev = truth[k - 1].T_W_I;
  const geometry::Pose3d& curr = truth[k].T_W_I;
  const geometry::Pose3d& next = truth[k + 1].T_W_I;
  const Eigen::Vector3d a_W = (next.p - 2.0 * curr.p + prev.p) / (dt * dt);
  FiniteDifference fd;
  fd.accel_m_s2 = curr.q.conjugate() * (a_W - Eigen::Vector3d(0, 0, -gravity));
  fd.gyro_rad_s = geometry::Log(Eigen::Quaterniond(prev.q.conjugate() * next.q)) / (2.0 * dt);
  fd.velocity_m_s = (next.p - prev.p) / (2.0 * dt);
  return fd;
}

TEST_P(ImuTest, NoiseFreeSamplesAreTheDerivativesOfTheTruth) {
  const Simulator simulator(test::SmallLog(GetParam()).WithoutNoise());
  const ImuLog imu = simulator.GenerateImu();
  ASSERT_EQ(imu.samples.size(), imu.truth.size());
  ASSERT_GT(imu.samples.size(), 4000u);
  double worst_accel = 0.0, worst_gyro = 0.0, worst_velocity = 0.0;
  size_t worst_accel_k = 0, worst_gyro_k = 0;
  for (size_t k = 1; k + 1 < imu.samples.size(); ++k) {
    const FiniteDifference fd = Differentiate(imu.truth, k, simulator.options().imu.gravity_m_s2);
    const double e_accel = (imu.samples[k].accel_m_s2 - fd.accel_m_s2).norm();
    const double e_gyro = (imu.samples[k].gyro_rad_s - fd.gyro_rad_s).norm();
    if (e_accel > worst_accel) worst_accel = e_accel, worst_accel_k = k;
    if (e_gyro > worst_gyro) worst_gyro = e_gyro, worst_gyro_k = k;
    worst_velocity = std::max(worst_velocity, (imu.truth[k].v_W_I - fd.velocity_m_s).norm());
  }
  // Central differences at 5 ms are accurate to O(dt^2) (~1e-5 here) plus rounding of
  // positions some hundred metres from the origin (~1e-13 m / dt^2 ~ 1e-8): far below the
  // discrete noise (0.028 m/s^2, 0.0024 rad/s).
  const auto& a = imu.samples[worst_accel_k];
  const auto& g = imu.samples[worst_gyro_k];
  EXPECT_LT(worst_accel, 2e-4)
      << "at sample " << worst_accel_k << ": imu " << a.accel_m_s2.transpose()
      << " vs finite difference "
      << Differentiate(imu.truth, worst_accel_k, 9.80665).accel_m_s2.transpose();
  EXPECT_LT(worst_gyro, 2e-5)
      << "at sample " << worst_gyro_k << ": imu " << g.gyro_rad_s.transpose()
      << " vs finite difference "
      << Differentiate(imu.truth, worst_gyro_k, 9.80665).gyro_rad_s.transpose();
  EXPECT_LT(worst_velocity, 1e-4) << "v_W_I disagrees with the differentiated positions";
}

TEST_P(ImuTest, NoiseAndBiasFollowTheDiscretizedDensities) {
  const SimulationOptions options = test::SmallLog(GetParam());
  const ImuLog noisy = Simulator(options).GenerateImu();
  const ImuLog exact = Simulator(options.WithoutNoise()).GenerateImu();
  ASSERT_EQ(noisy.samples.size(), exact.samples.size());
  const sensors::ImuNoise& density = options.imu.noise;
  const double rate = density.update_rate_hz;
  const double dt = 1.0 / rate;
  // sigma_d = sigma_c sqrt(rate) for white noise, sigma_c sqrt(dt) per bias step.
  const double expected[4] = {density.gyroscope_noise_density * std::sqrt(rate),
                              density.accelerometer_noise_density * std::sqrt(rate),
                              density.gyroscope_random_walk * std::sqrt(dt),
                              density.accelerometer_random_walk * std::sqrt(dt)};
  double sum[4] = {0, 0, 0, 0}, sum_sq[4] = {0, 0, 0, 0};
  const size_t n = noisy.samples.size();
  for (size_t k = 0; k + 1 < n; ++k) {
    const Eigen::Vector3d e[4] = {
        noisy.samples[k].gyro_rad_s - exact.samples[k].gyro_rad_s - noisy.gyro_bias[k],
        noisy.samples[k].accel_m_s2 - exact.samples[k].accel_m_s2 - noisy.accel_bias[k],
        noisy.gyro_bias[k + 1] - noisy.gyro_bias[k], noisy.accel_bias[k + 1] - noisy.accel_bias[k]};
    for (int i = 0; i < 4; ++i) {
      sum[i] += e[i].sum();
      sum_sq[i] += e[i].squaredNorm();
    }
  }
  const char* names[4] = {"gyro white noise", "accel white noise", "gyro bias step",
                          "accel bias step"};
  const double count = 3.0 * (n - 1);
  for (int i = 0; i < 4; ++i) {
    const double mean = sum[i] / count;
    const double sigma = std::sqrt(sum_sq[i] / count - mean * mean);
    // ~15000 draws: the sample sigma is within 5% (8 standard errors) and the mean within
    // 5 standard errors of zero.
    EXPECT_NEAR(sigma, expected[i], 0.05 * expected[i]) << names[i];
    EXPECT_LT(std::abs(mean), 5.0 * expected[i] / std::sqrt(count)) << names[i];
  }
  // The truth is the same with and without noise.
  EXPECT_EQ(noisy.truth.back().T_W_I.p, exact.truth.back().T_W_I.p);
}

INSTANTIATE_TEST_SUITE_P(Scenarios, ImuTest,
                         ::testing::Values(ScenarioType::kUrban, ScenarioType::kHighway,
                                           ScenarioType::kSkidSteer, ScenarioType::kStraight),
                         [](const auto& info) { return test::Name(info.param); });

}  // namespace
}  // namespace sim
}  // namespace autocal
