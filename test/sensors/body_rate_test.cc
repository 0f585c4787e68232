#include "autocal/sensors/body_rate.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "autocal/common/error.h"

namespace autocal {
namespace sensors {
namespace {

struct Drawn {
  std::vector<Eigen::Vector3d> truth;
  std::vector<GyroReading> readings;
};

// A ground vehicle's rates in its own axes (yaw rate turning at up to 0.5 rad/s, no roll or
// pitch rate), turned by `axes` and offset by a bias, read with white noise of `sigma`.
Drawn Turns(const Eigen::Matrix3d& axes, double sigma, int n, uint64_t seed) {
  std::mt19937_64 random(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  const Eigen::Vector3d bias(0.01, -0.02, 0.005);
  Drawn out;
  for (int k = 0; k < n; ++k) {
    const double t = 0.1 * k;
    const Eigen::Vector3d rate = axes * Eigen::Vector3d(0.0, 0.0, 0.5 * std::sin(0.3 * t));
    const Eigen::Vector3d noise(normal(random), normal(random), normal(random));
    out.truth.push_back(rate);
    out.readings.push_back({rate + bias + sigma * noise, sigma * sigma});
  }
  return out;
}

// The errors of the conditioned rates about the truth less the bias: their mean and covariance.
Eigen::Matrix3d ErrorCovariance(const Drawn& d, const BodyRatePrior& prior,
                                const Eigen::Vector3d& bias, Eigen::Matrix3d* stated) {
  Eigen::Matrix3d sum = Eigen::Matrix3d::Zero();
  *stated = Eigen::Matrix3d::Zero();
  for (size_t k = 0; k < d.readings.size(); ++k) {
    const BodyRate r = prior.Condition(d.readings[k]);
    const Eigen::Vector3d e = r.rate_rad_s - bias - d.truth[k];
    sum += e * e.transpose();
    *stated += r.covariance;
  }
  *stated /= static_cast<double>(d.readings.size());
  return sum / static_cast<double>(d.readings.size());
}

// The axis the vehicle turns about keeps its readings; the two it never turns about get the
// log's mean. The covariance stated for the error is the one measured on the turning axis
// (within 10 %); on the quiet ones it covers the error and stays far below the raw noise.
TEST(BodyRatePrior, KeepsTheTurnsAndTakesTheMeanOnAxesThatNeverTurn) {
  const double sigma = 0.03;
  const Drawn d = Turns(Eigen::Matrix3d::Identity(), sigma, 20000, 1);
  const BodyRatePrior prior = BodyRatePrior::Fit(d.readings);
  const Eigen::Vector3d bias(0.01, -0.02, 0.005);
  EXPECT_NEAR(prior.signal_covariance()(2, 2), 0.125, 0.005);
  EXPECT_LT((prior.signal_covariance().topLeftCorner<2, 2>().norm()), 3e-5);
  Eigen::Matrix3d stated;
  const Eigen::Matrix3d measured = ErrorCovariance(d, prior, bias, &stated);
  for (int i = 0; i < 2; ++i) {
    EXPECT_LE(measured(i, i), stated(i, i)) << i;
    EXPECT_LT(stated(i, i), 0.05 * sigma * sigma) << i;
  }
  EXPECT_NEAR(stated(2, 2), measured(2, 2), 0.1 * measured(2, 2));
  EXPECT_NEAR(measured(2, 2), sigma * sigma, 0.1 * sigma * sigma);
}

// The same when the vehicle's up axis is oblique to the gyro's axes (a tilted mount): the
// conditioning follows the excited direction, not the sensor's axes.
TEST(BodyRatePrior, FollowsAnObliqueTurningAxis) {
  const double sigma = 0.03;
  const Eigen::Matrix3d axes =
      Eigen::AngleAxisd(1.0, Eigen::Vector3d(1.0, 2.0, -0.5).normalized()).toRotationMatrix();
  const Drawn d = Turns(axes, sigma, 20000, 2);
  const BodyRatePrior prior = BodyRatePrior::Fit(d.readings);
  Eigen::Matrix3d stated;
  const Eigen::Matrix3d measured =
      ErrorCovariance(d, prior, Eigen::Vector3d(0.01, -0.02, 0.005), &stated);
  const Eigen::Vector3d up = axes.col(2);
  EXPECT_NEAR(up.dot(stated * up), up.dot(measured * up), 0.1 * up.dot(measured * up));
  const Eigen::Vector3d side = axes.col(0);
  EXPECT_LE(side.dot(measured * side), side.dot(stated * side));
  EXPECT_LT(side.dot(stated * side), 0.05 * sigma * sigma);
}

// Readings without noise are taken as they are.
TEST(BodyRatePrior, NoiselessReadingsAreTakenAsTheyAre) {
  Drawn d = Turns(Eigen::Matrix3d::Identity(), 0.0, 100, 3);
  const BodyRatePrior prior = BodyRatePrior::Fit(d.readings);
  const BodyRate r = prior.Condition(d.readings[17]);
  EXPECT_EQ(r.rate_rad_s, d.readings[17].rate_rad_s);
  EXPECT_TRUE(r.covariance.isZero(0.0));
}

TEST(BodyRatePrior, RejectsTooFewOrInvalidReadings) {
  EXPECT_THROW(BodyRatePrior::Fit({GyroReading()}), Error);
  std::vector<GyroReading> readings(3);
  readings[1].rate_rad_s.y() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(BodyRatePrior::Fit(readings), Error);
  readings[1].rate_rad_s.y() = 0.0;
  readings[2].noise_variance = -1.0;
  EXPECT_THROW(BodyRatePrior::Fit(readings), Error);
}

// A 100 Hz log turning about z (0.5 rad/s amplitude) with white noise of 0.05 rad/s per
// sample: averaged over 0.1 s (10 samples) every 0.2 s, the spread less the means' noise is the
// turning's 0.125 (rad/s)^2 about z and nothing about x and y.
TEST(BodyRatePrior, FitsToAWholeLog) {
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0.0, 0.05);
  ImuSamples imu;
  for (int k = 0; k < 60000; ++k) {
    ImuSample s;
    s.t_ns = static_cast<int64_t>(k) * 10'000'000;
    s.gyro_rad_s = Eigen::Vector3d(noise(rng), noise(rng), 0.5 * std::sin(0.01 * k) + noise(rng));
    imu.push_back(s);
  }
  const BodyRatePrior prior = BodyRatePrior::FitToLog(imu, 0.2, 0.1, 0.05);
  const Eigen::Matrix3d& c = prior.signal_covariance();
  EXPECT_NEAR(c(2, 2), 0.125, 0.01);
  EXPECT_LT(c(0, 0), 1e-4);
  EXPECT_LT(c(1, 1), 1e-4);
  EXPECT_LT(prior.mean_rad_s().norm(), 0.01);
  EXPECT_THROW(BodyRatePrior::FitToLog(imu, 0.0, 0.1, 0.05), Error);
  EXPECT_THROW(BodyRatePrior::FitToLog(imu, 0.2, -0.1, 0.05), Error);
}

}  // namespace
}  // namespace sensors
}  // namespace autocal
