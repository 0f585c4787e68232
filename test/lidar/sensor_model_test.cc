#include "autocal/lidar/sensor_model.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "autocal/common/error.h"
#include "autocal/common/units.h"

namespace autocal {
namespace lidar {
namespace {

// Points over every azimuth quadrant and the full elevation range of a 3D LiDAR.
std::vector<SphericalPoint> SampleSpherical(int count, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> range(0.5, 120.0);
  std::uniform_real_distribution<double> azimuth(-kPi, kPi);
  std::uniform_real_distribution<double> elevation(-0.5 * kPi + 1e-6, 0.5 * kPi - 1e-6);
  std::vector<SphericalPoint> out;
  for (int i = 0; i < count; ++i) out.push_back({range(rng), azimuth(rng), elevation(rng)});
  return out;
}

// Eq. (1.0): r = c t / (2 n). In vacuum a 1 ns round trip is 0.149896229 m; in air a 100 m
// target answers 0.18 ns later than in vacuum, which a range taken at c would read as 2.75 cm
// farther.
TEST(SensorModelTest, TimeOfFlightIsHalfTheRoundTripAtTheSpeedOfLightInAir) {
  EXPECT_DOUBLE_EQ(RangeFromRoundTripTime(1e-9, 1.0), 0.149896229);
  EXPECT_DOUBLE_EQ(RangeSigmaFromTimingSigma(1e-9, 1.0), 0.149896229);
  EXPECT_NEAR(RangeFromRoundTripTime(RoundTripTimeFromRange(87.5)), 87.5, 1e-12);
  const double in_air_s = RoundTripTimeFromRange(100.0);
  EXPECT_NEAR(in_air_s, 2.0 * 100.0 * 1.000275 / 299792458.0, 1e-21);
  EXPECT_NEAR(in_air_s - RoundTripTimeFromRange(100.0, 1.0), 0.1834e-9, 0.0001e-9);
  EXPECT_NEAR(RangeFromRoundTripTime(in_air_s, 1.0) - 100.0, 0.0275, 1e-6);
  // A stopwatch of 67 ps (1-sigma) ranges to 1 cm.
  EXPECT_NEAR(RangeSigmaFromTimingSigma(66.7e-12), 0.01, 1e-5);
  EXPECT_THROW(RangeFromRoundTripTime(-1e-9), Error);
  EXPECT_THROW(RangeFromRoundTripTime(std::nan("")), Error);
  EXPECT_THROW(RoundTripTimeFromRange(10.0, 0.99), Error);
  EXPECT_THROW(RangeSigmaFromTimingSigma(-1.0), Error);
}

TEST(SensorModelTest, SphericalRoundTripCoversAllQuadrants) {
  int quadrant_counts[4] = {0, 0, 0, 0};
  for (const SphericalPoint& s : SampleSpherical(2000, 7)) {
    const Eigen::Vector3d p = SphericalToCartesian(s);
    const SphericalPoint back = CartesianToSpherical(p);
    EXPECT_NEAR(back.range_m, s.range_m, 1e-9 * s.range_m) << "p = " << p.transpose();
    EXPECT_NEAR(back.azimuth_rad, s.azimuth_rad, 1e-9) << "p = " << p.transpose();
    EXPECT_NEAR(back.elevation_rad, s.elevation_rad, 1e-9) << "p = " << p.transpose();
    ++quadrant_counts[(p.x() >= 0 ? 0 : 1) + (p.y() >= 0 ? 0 : 2)];
  }
  for (int count : quadrant_counts) EXPECT_GT(count, 300);
}

TEST(SensorModelTest, CartesianRoundTripAndGeometry) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> coordinate(-80.0, 80.0);
  for (int i = 0; i < 2000; ++i) {
    const Eigen::Vector3d p(coordinate(rng), coordinate(rng), 0.3 * coordinate(rng));
    const SphericalPoint s = CartesianToSpherical(p);
    EXPECT_TRUE(SphericalToCartesian(s).isApprox(p, 1e-12)) << p.transpose();
    // z = r sin(elevation): the course's printed model drops the range factor.
    EXPECT_NEAR(p.z(), s.range_m * std::sin(s.elevation_rad), 1e-9);
    // Azimuth is counter-clockwise from +x in the xy plane.
    EXPECT_NEAR(std::cos(s.azimuth_rad), p.x() / std::hypot(p.x(), p.y()), 1e-12);
    EXPECT_NEAR(std::sin(s.azimuth_rad), p.y() / std::hypot(p.x(), p.y()), 1e-12);
  }
}

TEST(SensorModelTest, OppositeQuadrantsAreDistinguished) {
  // arctan(y / x) maps (1, 1) and (-1, -1) to the same angle; atan2 must not.
  const SphericalPoint a = CartesianToSpherical(Eigen::Vector3d(1.0, 1.0, 0.0));
  const SphericalPoint b = CartesianToSpherical(Eigen::Vector3d(-1.0, -1.0, 0.0));
  EXPECT_NEAR(a.azimuth_rad, 0.25 * kPi, 1e-15);
  EXPECT_NEAR(b.azimuth_rad, -0.75 * kPi, 1e-15);
  const SphericalPoint origin = CartesianToSpherical(Eigen::Vector3d::Zero());
  EXPECT_EQ(origin.range_m, 0.0);
  EXPECT_EQ(origin.azimuth_rad, 0.0);
  EXPECT_EQ(origin.elevation_rad, 0.0);
  const SphericalPoint up = CartesianToSpherical(Eigen::Vector3d(0.0, 0.0, 5.0));
  EXPECT_NEAR(up.elevation_rad, 0.5 * kPi, 1e-15);
}

// A zero's sign is no side: (-1, -0, 0) lies on the negative x axis, azimuth pi (not -pi,
// outside (-pi, pi]), and (-0, 0, 1) on the z axis, azimuth 0 (not pi). Rotations and
// products make such zeros, e.g. Rz(pi) applied to (0, 0, 1) gives x = -0.
TEST(SensorModelTest, SignedZerosGiveTheDocumentedAzimuths) {
  const double kMinusZero = -0.0;
  for (const double y : {0.0, kMinusZero}) {
    EXPECT_EQ(CartesianToSpherical(Eigen::Vector3d(-1.0, y, 0.0)).azimuth_rad, kPi) << y;
    EXPECT_EQ(CartesianToSpherical(Eigen::Vector3d(-1.0, y, 2.0)).azimuth_rad, kPi) << y;
    EXPECT_EQ(CartesianToPolar(Eigen::Vector2d(-1.0, y)).azimuth_rad, kPi) << y;
    EXPECT_EQ(CartesianToSpherical(Eigen::Vector3d(1.0, y, 0.0)).azimuth_rad, 0.0) << y;
    for (const double x : {0.0, kMinusZero}) {
      for (const double z : {1.0, -1.0, 0.0, kMinusZero}) {
        const SphericalPoint s = CartesianToSpherical(Eigen::Vector3d(x, y, z));
        EXPECT_EQ(s.azimuth_rad, 0.0) << x << " " << y << " " << z;
        EXPECT_FALSE(std::signbit(s.azimuth_rad)) << x << " " << y << " " << z;
        EXPECT_EQ(s.elevation_rad, z == 0.0 ? 0.0 : std::copysign(0.5 * kPi, z));
      }
      EXPECT_EQ(CartesianToPolar(Eigen::Vector2d(x, y)).azimuth_rad, 0.0) << x << " " << y;
    }
  }
  EXPECT_TRUE(
      std::isnan(CartesianToSpherical(Eigen::Vector3d(std::nan(""), 0.0, 1.0)).azimuth_rad));
}

TEST(SensorModelTest, TwoDimensionalModelIsTheZeroElevationCase) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> range(0.1, 30.0);
  std::uniform_real_distribution<double> azimuth(-kPi, kPi);
  for (int i = 0; i < 500; ++i) {
    const PolarPoint s{range(rng), azimuth(rng)};
    const Eigen::Vector2d p = PolarToCartesian(s);
    const PolarPoint back = CartesianToPolar(p);
    EXPECT_NEAR(back.range_m, s.range_m, 1e-12 * s.range_m);
    EXPECT_NEAR(back.azimuth_rad, s.azimuth_rad, 1e-12);
    const Eigen::Vector3d p3 = SphericalToCartesian({s.range_m, s.azimuth_rad, 0.0});
    EXPECT_NEAR(p3.z(), 0.0, 1e-15);
    EXPECT_TRUE(p3.head<2>().isApprox(p, 1e-14));
  }
}

TEST(SensorModelTest, JacobianMatchesCentralDifferences) {
  for (const SphericalPoint& s : SampleSpherical(200, 5)) {
    const Eigen::Matrix3d J = InverseModelJacobian(s);
    Eigen::Matrix3d numeric;
    const double h = 1e-6;
    for (int k = 0; k < 3; ++k) {
      SphericalPoint plus = s;
      SphericalPoint minus = s;
      double* fields_plus[3] = {&plus.range_m, &plus.azimuth_rad, &plus.elevation_rad};
      double* fields_minus[3] = {&minus.range_m, &minus.azimuth_rad, &minus.elevation_rad};
      *fields_plus[k] += h;
      *fields_minus[k] -= h;
      numeric.col(k) = (SphericalToCartesian(plus) - SphericalToCartesian(minus)) / (2 * h);
    }
    EXPECT_TRUE(J.isApprox(numeric, 1e-7)) << "analytic\n" << J << "\nnumeric\n" << numeric;
  }
}

// Monte Carlo covariance of the inverse model under Gaussian spherical noise.
Eigen::Matrix3d MonteCarloCovariance(const SphericalPoint& s, const SphericalNoise& noise,
                                     int samples, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  Eigen::Matrix3d sum_outer = Eigen::Matrix3d::Zero();
  const Eigen::Vector3d truth = SphericalToCartesian(s);
  for (int i = 0; i < samples; ++i) {
    const SphericalPoint noisy{s.range_m + noise.range_sigma_m * normal(rng),
                               s.azimuth_rad + noise.azimuth_sigma_rad * normal(rng),
                               s.elevation_rad + noise.elevation_sigma_rad * normal(rng)};
    const Eigen::Vector3d d = SphericalToCartesian(noisy) - truth;
    sum += d;
    sum_outer += d * d.transpose();
  }
  const Eigen::Vector3d mean = sum / samples;
  return sum_outer / samples - mean * mean.transpose();
}

TEST(SensorModelTest, FirstOrderCovarianceMatchesMonteCarlo) {
  // Range noise dominates near the sensor, angular noise far away: both regimes.
  const SphericalNoise noise{0.02, 0.2 * kDegToRad, 0.1 * kDegToRad};
  constexpr int kSamples = 200000;
  for (const SphericalPoint& s : SampleSpherical(6, 21)) {
    const Eigen::Matrix3d predicted = CartesianCovariance(s, noise);
    const Eigen::Matrix3d empirical = MonteCarloCovariance(s, noise, kSamples, 99);
    // Sampling error of a covariance from N draws is about sqrt(2 / N) = 0.3 % of its
    // size; the first-order (linearization) error is O(sigma_angle^2), far smaller.
    const double tolerance = 0.02 * predicted.norm();
    EXPECT_LT((predicted - empirical).cwiseAbs().maxCoeff(), tolerance)
        << "r = " << s.range_m << " az = " << s.azimuth_rad << " el = " << s.elevation_rad
        << "\npredicted\n"
        << predicted << "\nMonte Carlo\n"
        << empirical;
  }
}

TEST(SensorModelTest, TwoDimensionalCovarianceMatchesThreeDimensionalBlock) {
  const SphericalNoise noise{0.03, 0.005, 0.0};
  const PolarPoint s{25.0, 2.5};
  const Eigen::Matrix3d full = CartesianCovariance({s.range_m, s.azimuth_rad, 0.0}, noise);
  const Eigen::Matrix2d planar =
      CartesianCovariance2d(s, noise.range_sigma_m, noise.azimuth_sigma_rad);
  EXPECT_TRUE((full.topLeftCorner<2, 2>().isApprox(planar, 1e-12))) << full << "\n" << planar;
  // Across the beam the spread is r * sigma_azimuth, along it sigma_range.
  const Eigen::Vector2d along(std::cos(s.azimuth_rad), std::sin(s.azimuth_rad));
  const Eigen::Vector2d across(-along.y(), along.x());
  EXPECT_NEAR(along.dot(planar * along), 0.03 * 0.03, 1e-12);
  EXPECT_NEAR(across.dot(planar * across), std::pow(25.0 * 0.005, 2), 1e-12);
}

}  // namespace
}  // namespace lidar
}  // namespace autocal
