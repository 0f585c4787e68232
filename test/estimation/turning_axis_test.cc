// The axis the vehicle turns about (Eq. K13c): the principal axis of the body rates' spread,
// oriented along the up axis given, taken only when its standard error is small; readings
// added one at a time give the two-pass spread's axis.
#include "estimation/turning_axis.h"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

namespace autocal {
namespace estimation {
namespace internal {
namespace {

constexpr double kDeg = M_PI / 180.0;

// n body rates of a vehicle turning about `axis` at up to 0.5 rad/s, with white gyro noise
// `noise_rad_s` per axis.
std::vector<Eigen::Vector3d> Rates(const Eigen::Vector3d& axis, int n, double noise_rad_s,
                                   unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> yaw_rate(-0.5, 0.5);
  std::normal_distribution<double> noise(0.0, noise_rad_s);
  std::vector<Eigen::Vector3d> rates;
  for (int i = 0; i < n; ++i) {
    rates.push_back(yaw_rate(rng) * axis + Eigen::Vector3d(noise(rng), noise(rng), noise(rng)));
  }
  return rates;
}

Eigen::Matrix3d TwoPassSpread(const std::vector<Eigen::Vector3d>& rates) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& w : rates) mean += w / static_cast<double>(rates.size());
  Eigen::Matrix3d spread = Eigen::Matrix3d::Zero();
  for (const Eigen::Vector3d& w : rates) spread += (w - mean) * (w - mean).transpose();
  return spread / static_cast<double>(rates.size());
}

// The IMU mounted with its z axis 5 degrees off the vehicle's up axis, about x.
const Eigen::Vector3d kAxis =
    Eigen::AngleAxisd(5.0 * kDeg, Eigen::Vector3d::UnitX()) * Eigen::Vector3d::UnitZ();

TEST(TurningAxis, IsThePrincipalAxisOrientedUp) {
  const std::vector<Eigen::Vector3d> rates = Rates(kAxis, 300, 0.005, 1);
  const auto up =
      PrincipalTurningAxis(300, TwoPassSpread(rates), Eigen::Vector3d::UnitZ(), 1.0 * kDeg);
  ASSERT_TRUE(up.has_value());
  EXPECT_LT(std::acos(std::min(1.0, up->dot(kAxis))), 0.2 * kDeg);
  // Given the opposite up axis, the opposite orientation.
  const auto down =
      PrincipalTurningAxis(300, TwoPassSpread(rates), -Eigen::Vector3d::UnitZ(), 1.0 * kDeg);
  ASSERT_TRUE(down.has_value());
  EXPECT_NEAR((*down + *up).norm(), 0.0, 1e-15);
}

TEST(TurningAxis, NeedsItsStandardErrorBelowTheLimit) {
  const std::vector<Eigen::Vector3d> rates = Rates(kAxis, 30, 0.02, 2);
  const Eigen::Matrix3d spread = TwoPassSpread(rates);
  const Eigen::Vector3d l = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(spread).eigenvalues();
  const double error_rad = std::sqrt(l(2) * l(1) / (30 * (l(2) - l(1)) * (l(2) - l(1))));
  EXPECT_GT(error_rad, 0.3 * kDeg);  // about 0.7 deg: thirty readings of a noisy gyro
  EXPECT_TRUE(PrincipalTurningAxis(30, spread, Eigen::Vector3d::UnitZ(), 1.01 * error_rad));
  EXPECT_FALSE(PrincipalTurningAxis(30, spread, Eigen::Vector3d::UnitZ(), 0.99 * error_rad));
  // No turns: an isotropic spread has no principal axis.
  EXPECT_FALSE(
      PrincipalTurningAxis(300, Eigen::Matrix3d::Identity(), Eigen::Vector3d::UnitZ(), 1.0 * kDeg));
  // A straight drive pitching on its suspension: the spread's principal axis is the pitch
  // axis, not the one nearest up, and says nothing about the turns.
  std::vector<Eigen::Vector3d> pitching = Rates(Eigen::Vector3d::UnitY(), 300, 0.005, 5);
  for (Eigen::Vector3d& w : pitching) w += 0.1 * w.y() * kAxis;  // and a little yaw with it
  EXPECT_FALSE(
      PrincipalTurningAxis(300, TwoPassSpread(pitching), Eigen::Vector3d::UnitZ(), 1.0 * kDeg));
  // Fewer than three readings, or no limit.
  EXPECT_FALSE(PrincipalTurningAxis(2, spread, Eigen::Vector3d::UnitZ(), 1.0 * kDeg));
  EXPECT_FALSE(PrincipalTurningAxis(30, spread, Eigen::Vector3d::UnitZ(), 0.0));
}

TEST(TurningRateSpread, GivesTheTwoPassAxisOneReadingAtATime) {
  const std::vector<Eigen::Vector3d> rates = Rates(kAxis, 500, 0.01, 4);
  TurningRateSpread spread;
  EXPECT_FALSE(spread.Axis(Eigen::Vector3d::UnitZ(), 1.0 * kDeg));
  for (const Eigen::Vector3d& w : rates) spread.Add(w);
  EXPECT_EQ(spread.count(), 500);
  const auto streamed = spread.Axis(Eigen::Vector3d::UnitZ(), 1.0 * kDeg);
  const auto batch =
      PrincipalTurningAxis(500, TwoPassSpread(rates), Eigen::Vector3d::UnitZ(), 1.0 * kDeg);
  ASSERT_TRUE(streamed.has_value());
  ASSERT_TRUE(batch.has_value());
  EXPECT_LT((*streamed - *batch).norm(), 1e-12);
}

}  // namespace
}  // namespace internal
}  // namespace estimation
}  // namespace autocal
