#pragma once

// Synthetic LiDAR scenes with exact geometry for the lidar tests: a ground plane z = 0 and
// axis-aligned boxes (buildings, poles, parked cars, a lead vehicle), scanned by a spinning
// multi-beam LiDAR by ray casting. Every point carries its time within the sweep, and the
// sensor pose may change during the sweep, so motion distortion is reproduced exactly.

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <random>
#include <vector>

#include "autocal/common/units.h"
#include "autocal/geometry/se3.h"
#include "autocal/lidar/point_cloud.h"

namespace autocal {
namespace test {

struct Box {
  Eigen::Vector3d min_corner;
  Eigen::Vector3d max_corner;
};

struct Scene {
  bool has_ground = true;  // the plane z = 0
  std::vector<Box> boxes;
};

// A street along +x: buildings with varying setbacks on both sides, poles and parked cars.
// Faces with normals along x, y and z at many positions constrain all six motion axes.
inline Scene MakeStreetScene(uint64_t seed, double length_m = 160.0) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  Scene scene;
  for (int side = -1; side <= 1; side += 2) {
    double x = -length_m / 2;
    while (x < length_m / 2) {
      const double width = 8.0 + 12.0 * uniform(rng);
      const double setback = 9.0 + 4.0 * uniform(rng);
      const double depth = 10.0 + 10.0 * uniform(rng);
      const double height = 6.0 + 14.0 * uniform(rng);
      const double near_y = side * setback;
      const double far_y = side * (setback + depth);
      scene.boxes.push_back(Box{Eigen::Vector3d(x, std::min(near_y, far_y), 0.0),
                                Eigen::Vector3d(x + width, std::max(near_y, far_y), height)});
      x += width + 2.0 + 6.0 * uniform(rng);
    }
    for (double pole_x = -length_m / 2 + 5.0; pole_x < length_m / 2;
         pole_x += 12.0 + 6.0 * uniform(rng)) {
      const double y = side * (6.5 + uniform(rng));
      scene.boxes.push_back(Box{Eigen::Vector3d(pole_x, y - 0.15, 0.0),
                                Eigen::Vector3d(pole_x + 0.3, y + 0.15, 4.0 + 2.0 * uniform(rng))});
    }
    for (double car_x = -length_m / 2 + 9.0; car_x < length_m / 2;
         car_x += 15.0 + 20.0 * uniform(rng)) {
      const double y = side * 4.8;
      scene.boxes.push_back(
          Box{Eigen::Vector3d(car_x, y - 0.9, 0.0), Eigen::Vector3d(car_x + 4.5, y + 0.9, 1.5)});
    }
  }
  return scene;
}

struct ScanPattern {
  int num_beams = 32;
  double min_elevation_deg = -25.0;
  double max_elevation_deg = 15.0;
  int azimuth_steps = 900;  // 0.4 deg
  double min_range_m = 1.0;
  double max_range_m = 80.0;
  double range_noise_m = 0.0;
  double sweep_period_s = 0.1;
};

// Distance along the unit ray (o, d) to the first surface of the scene, or infinity.
inline double CastRay(const Scene& scene, const Eigen::Vector3d& o, const Eigen::Vector3d& d) {
  double best = std::numeric_limits<double>::infinity();
  if (scene.has_ground && d.z() < -1e-12 && o.z() > 0.0) best = -o.z() / d.z();
  for (const Box& box : scene.boxes) {
    // Slab test.
    double t_near = 0.0;
    double t_far = best;
    bool hit = true;
    for (int axis = 0; axis < 3 && hit; ++axis) {
      if (std::abs(d(axis)) < 1e-12) {
        hit = o(axis) >= box.min_corner(axis) && o(axis) <= box.max_corner(axis);
        continue;
      }
      double t0 = (box.min_corner(axis) - o(axis)) / d(axis);
      double t1 = (box.max_corner(axis) - o(axis)) / d(axis);
      if (t0 > t1) std::swap(t0, t1);
      t_near = std::max(t_near, t0);
      t_far = std::min(t_far, t1);
      hit = t_near <= t_far;
    }
    if (hit && t_near > 1e-9 && t_near < best) best = t_near;
  }
  return best;
}

// One sweep. pose_at(tau) is T_W_L at time tau in [0, sweep_period_s) after the sweep stamp;
// the beam at azimuth step k fires at tau = k / azimuth_steps * period. Points are in the
// sensor frame at their own firing time (what a real LiDAR reports), with time_s = tau.
inline lidar::PointCloud SimulateSweep(const Scene& scene,
                                       const std::function<geometry::Pose3d(double)>& pose_at,
                                       const ScanPattern& pattern, std::mt19937_64* rng) {
  std::normal_distribution<double> noise(0.0, 1.0);
  std::vector<Eigen::Vector3d> points;
  std::vector<double> times;
  points.reserve(static_cast<size_t>(pattern.num_beams * pattern.azimuth_steps));
  for (int k = 0; k < pattern.azimuth_steps; ++k) {
    const double tau = pattern.sweep_period_s * k / pattern.azimuth_steps;
    const geometry::Pose3d T_W_L = pose_at(tau);
    const Eigen::Matrix3d R_W_L = T_W_L.R();
    const double azimuth = -kPi + 2.0 * kPi * k / pattern.azimuth_steps;
    for (int b = 0; b < pattern.num_beams; ++b) {
      const double elevation =
          (pattern.min_elevation_deg + (pattern.max_elevation_deg - pattern.min_elevation_deg) * b /
                                           std::max(1, pattern.num_beams - 1)) *
          kDegToRad;
      const Eigen::Vector3d dir_L(std::cos(elevation) * std::cos(azimuth),
                                  std::cos(elevation) * std::sin(azimuth), std::sin(elevation));
      const double range = CastRay(scene, T_W_L.p, R_W_L * dir_L);
      if (!(range >= pattern.min_range_m && range <= pattern.max_range_m)) continue;
      const double measured = range + pattern.range_noise_m * noise(*rng);
      points.push_back(measured * dir_L);
      times.push_back(tau);
    }
  }
  lidar::PointCloud cloud;
  cloud.points.resize(3, static_cast<Eigen::Index>(points.size()));
  cloud.time_s.resize(static_cast<Eigen::Index>(points.size()));
  for (size_t i = 0; i < points.size(); ++i) {
    cloud.points.col(i) = points[i];
    cloud.time_s(i) = times[i];
  }
  return cloud;
}

// A sweep from a pose that does not move during the sweep.
inline lidar::PointCloud SimulateStaticSweep(const Scene& scene, const geometry::Pose3d& T_W_L,
                                             const ScanPattern& pattern, std::mt19937_64* rng) {
  return SimulateSweep(
      scene, [&](double) { return T_W_L; }, pattern, rng);
}

// Pose with yaw, pitch, roll (Z-Y-X) in degrees and translation in metres.
inline geometry::Pose3d MakePose(double x, double y, double z, double yaw_deg, double pitch_deg,
                                 double roll_deg) {
  const Eigen::Quaterniond q = Eigen::AngleAxisd(yaw_deg * kDegToRad, Eigen::Vector3d::UnitZ()) *
                               Eigen::AngleAxisd(pitch_deg * kDegToRad, Eigen::Vector3d::UnitY()) *
                               Eigen::AngleAxisd(roll_deg * kDegToRad, Eigen::Vector3d::UnitX());
  return geometry::Pose3d(q, Eigen::Vector3d(x, y, z));
}

inline double RotationErrorDeg(const geometry::Pose3d& a, const geometry::Pose3d& b) {
  return geometry::RotationErrorRad(a, b) * kRadToDeg;
}

}  // namespace test
}  // namespace autocal
