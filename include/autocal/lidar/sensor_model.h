#pragma once

// LiDAR sensor models (docs/lidar.md §1). A LiDAR ranges by time of flight: the stopwatch's
// round-trip time t of a pulse gives r = v t / 2 with v = c / n, the speed of light in air
// (eq. 1.0). A spinning LiDAR reports each return in spherical coordinates: range r, azimuth alpha
// measured counter-clockwise from the sensor's x axis in its xy plane, and elevation epsilon
// measured up from that plane.
//
//   inverse model (eq. 1.1): p = h^-1(r, alpha, eps) = r (cos eps cos alpha,
//                                                        cos eps sin alpha,
//                                                        sin eps)
//   forward model (eq. 1.2): h(p) = (|p|, atan2(y, x), atan2(z, sqrt(x^2 + y^2)))
//
// The forward model uses atan2 so that every quadrant round-trips (arctan(y/x) cannot tell
// (x, y) from (-x, -y)), and the elevation uses atan2 rather than arcsin(z/r) so that it
// stays accurate near +-90 degrees. A 2D LiDAR is the special case eps = 0, z = 0.

#include <Eigen/Core>

#include "autocal/common/units.h"

namespace autocal {
namespace lidar {

// Time of flight (eq. 1.0). The speed of light in vacuum, exact by the SI definition of the
// metre, and the refractive index of air that slows it (dry air at 15 C and 101.325 kPa for
// near-infrared light, 1.00027 to 1.00028 over the 850 to 1550 nm of automotive LiDARs; it
// moves with temperature, pressure and humidity by parts in 10^5, the course's "the speed of
// light varies").
constexpr double kSpeedOfLightVacuumMS = 299792458.0;
constexpr double kAirRefractiveIndex = 1.000275;

// r = c t / (2 n): half the round trip. Throws autocal::Error for a negative or non-finite
// time, or an index below 1.
double RangeFromRoundTripTime(double round_trip_s, double refractive_index = kAirRefractiveIndex);
// Its inverse, t = 2 n r / c.
double RoundTripTimeFromRange(double range_m, double refractive_index = kAirRefractiveIndex);
// The range sigma of a stopwatch with timing sigma sigma_t: sigma_r = c sigma_t / (2 n) (eq.
// 1.0 is linear in t); 1 ns is 0.15 m, so centimetre ranging needs tens of picoseconds.
double RangeSigmaFromTimingSigma(double timing_sigma_s,
                                 double refractive_index = kAirRefractiveIndex);

struct SphericalPoint {
  double range_m = 0.0;
  double azimuth_rad = 0.0;    // in (-pi, pi]
  double elevation_rad = 0.0;  // in [-pi/2, pi/2]
};

struct PolarPoint {
  double range_m = 0.0;
  double azimuth_rad = 0.0;  // in (-pi, pi]
};

// Inverse sensor model, eq. (1.1).
Eigen::Vector3d SphericalToCartesian(const SphericalPoint& s);

// Forward sensor model, eq. (1.2). The origin maps to range 0 with both angles 0; a point
// on the z axis gets azimuth 0. Zeros count alike whatever their sign: (-1, -0, 0) has
// azimuth pi and (-0, 0, 1) azimuth 0.
SphericalPoint CartesianToSpherical(const Eigen::Vector3d& p);

// 2D LiDAR (eq. 1.3): polar coordinates in the sensor's xy plane. CartesianToPolar gives the
// azimuth of CartesianToSpherical: 0 at the origin, pi on the negative x axis.
Eigen::Vector2d PolarToCartesian(const PolarPoint& s);
PolarPoint CartesianToPolar(const Eigen::Vector2d& p);

// Jacobian of the inverse model d p / d (r, alpha, eps), eq. (1.4).
Eigen::Matrix3d InverseModelJacobian(const SphericalPoint& s);

// Independent zero-mean Gaussian noise on the three spherical measurements (1-sigma).
// Defaults: a typical automotive spinning LiDAR (2 cm range, 0.1 deg encoder and beam
// angle uncertainty).
struct SphericalNoise {
  double range_sigma_m = 0.02;
  double azimuth_sigma_rad = 0.1 * kDegToRad;
  double elevation_sigma_rad = 0.1 * kDegToRad;
};

// First-order Cartesian covariance of a point measured at s, eq. (1.5):
// Sigma_p = J Sigma_s J^T with J = InverseModelJacobian(s).
Eigen::Matrix3d CartesianCovariance(const SphericalPoint& s, const SphericalNoise& noise);

// The same for the 2D model (eq. 1.6).
Eigen::Matrix2d CartesianCovariance2d(const PolarPoint& s, double range_sigma_m,
                                      double azimuth_sigma_rad);

}  // namespace lidar
}  // namespace autocal
