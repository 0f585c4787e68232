#include "autocal/lidar/sensor_model.h"

#include <cmath>
#include <string>

#include "autocal/common/error.h"

namespace autocal {
namespace lidar {
namespace {

// atan2(y, x) in (-pi, pi], 0 when x = y = 0. Adding +0 turns a signed zero into +0 (IEEE:
// -0 + +0 = +0), which atan2 would otherwise read as a side: atan2(-0, -1) = -pi and
// atan2(+0, -0) = pi. atan2(+0, +0) is 0 on IEEE platforms.
double Azimuth(double x, double y) { return std::atan2(y + 0.0, x + 0.0); }

// The speed of light in a medium of `refractive_index`, refused below 1 (faster than in vacuum).
double SpeedOfLightMS(double refractive_index) {
  if (!(refractive_index >= 1.0) || !std::isfinite(refractive_index)) {
    throw Error("time of flight: the refractive index must be a finite number >= 1, got " +
                std::to_string(refractive_index));
  }
  return kSpeedOfLightVacuumMS / refractive_index;
}

void RequireNonNegative(double value, const char* what) {
  if (!(value >= 0.0) || !std::isfinite(value)) {
    throw Error(std::string("time of flight: ") + what + " must be a finite number >= 0, got " +
                std::to_string(value));
  }
}

}  // namespace

double RangeFromRoundTripTime(double round_trip_s, double refractive_index) {
  RequireNonNegative(round_trip_s, "the round-trip time");
  return 0.5 * SpeedOfLightMS(refractive_index) * round_trip_s;
}

double RoundTripTimeFromRange(double range_m, double refractive_index) {
  RequireNonNegative(range_m, "the range");
  return 2.0 * range_m / SpeedOfLightMS(refractive_index);
}

double RangeSigmaFromTimingSigma(double timing_sigma_s, double refractive_index) {
  RequireNonNegative(timing_sigma_s, "the timing sigma");
  return 0.5 * SpeedOfLightMS(refractive_index) * timing_sigma_s;
}

Eigen::Vector3d SphericalToCartesian(const SphericalPoint& s) {
  const double ce = std::cos(s.elevation_rad);
  return Eigen::Vector3d(s.range_m * ce * std::cos(s.azimuth_rad),
                         s.range_m * ce * std::sin(s.azimuth_rad),
                         s.range_m * std::sin(s.elevation_rad));
}

SphericalPoint CartesianToSpherical(const Eigen::Vector3d& p) {
  const double horizontal = std::hypot(p.x(), p.y());
  SphericalPoint s;
  s.range_m = p.norm();
  s.azimuth_rad = Azimuth(p.x(), p.y());
  // horizontal >= +0, so the elevation is 0 at the origin and +-pi/2 on the z axis.
  s.elevation_rad = std::atan2(p.z(), horizontal);
  return s;
}

Eigen::Vector2d PolarToCartesian(const PolarPoint& s) {
  return Eigen::Vector2d(s.range_m * std::cos(s.azimuth_rad), s.range_m * std::sin(s.azimuth_rad));
}

PolarPoint CartesianToPolar(const Eigen::Vector2d& p) {
  PolarPoint s;
  s.range_m = p.norm();
  s.azimuth_rad = Azimuth(p.x(), p.y());
  return s;
}

Eigen::Matrix3d InverseModelJacobian(const SphericalPoint& s) {
  const double ca = std::cos(s.azimuth_rad);
  const double sa = std::sin(s.azimuth_rad);
  const double ce = std::cos(s.elevation_rad);
  const double se = std::sin(s.elevation_rad);
  const double r = s.range_m;
  Eigen::Matrix3d J;
  // Columns: d/dr, d/dalpha, d/deps of eq. (1.1).
  J << ce * ca, -r * ce * sa, -r * se * ca,  //
      ce * sa, r * ce * ca, -r * se * sa,    //
      se, 0.0, r * ce;
  return J;
}

Eigen::Matrix3d CartesianCovariance(const SphericalPoint& s, const SphericalNoise& noise) {
  const Eigen::Matrix3d J = InverseModelJacobian(s);
  const Eigen::Vector3d variances(noise.range_sigma_m * noise.range_sigma_m,
                                  noise.azimuth_sigma_rad * noise.azimuth_sigma_rad,
                                  noise.elevation_sigma_rad * noise.elevation_sigma_rad);
  return J * variances.asDiagonal() * J.transpose();
}

Eigen::Matrix2d CartesianCovariance2d(const PolarPoint& s, double range_sigma_m,
                                      double azimuth_sigma_rad) {
  const double ca = std::cos(s.azimuth_rad);
  const double sa = std::sin(s.azimuth_rad);
  Eigen::Matrix2d J;
  J << ca, -s.range_m * sa,  //
      sa, s.range_m * ca;
  const Eigen::Vector2d variances(range_sigma_m * range_sigma_m,
                                  azimuth_sigma_rad * azimuth_sigma_rad);
  return J * variances.asDiagonal() * J.transpose();
}

}  // namespace lidar
}  // namespace autocal
