#include "autocal/estimation/plane_map.h"

#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

namespace autocal {
namespace estimation {
namespace {

// Ground z = 0 on [0, 20] x [-5, 5], a wall x = 20 up to 3 m, and a thin pole at (5, 3).
Eigen::Matrix3Xd Scene(double noise_m) {
  std::mt19937 rng(1);
  std::normal_distribution<double> n(0.0, noise_m);
  std::vector<Eigen::Vector3d> points;
  for (double x = 0.0; x <= 20.0; x += 0.1) {
    for (double y = -5.0; y <= 5.0; y += 0.1) points.emplace_back(x, y, n(rng));
  }
  for (double y = -5.0; y <= 5.0; y += 0.1) {
    for (double z = 0.1; z <= 3.0; z += 0.1) points.emplace_back(20.0 + n(rng), y, z);
  }
  for (double z = 0.5; z <= 4.0; z += 0.02) points.emplace_back(5.0, 3.0, z);
  Eigen::Matrix3Xd out(3, static_cast<Eigen::Index>(points.size()));
  for (size_t i = 0; i < points.size(); ++i) out.col(static_cast<Eigen::Index>(i)) = points[i];
  return out;
}

TEST(PlaneMap, FindsGroundAndWallPlanes) {
  const PlaneMap map(Scene(0.005));
  lidar::Plane plane;
  ASSERT_TRUE(map.FindPlane(Eigen::Vector3d(7.3, -1.2, 0.05), &plane));
  EXPECT_GT(std::abs(plane.normal.z()), 0.999);
  EXPECT_NEAR(plane.SignedDistance(Eigen::Vector3d(7.3, -1.2, 0.0)), 0.0, 0.01);
  ASSERT_TRUE(map.FindPlane(Eigen::Vector3d(19.9, 2.0, 1.5), &plane));
  EXPECT_GT(std::abs(plane.normal.x()), 0.999);
  EXPECT_NEAR(plane.SignedDistance(Eigen::Vector3d(20.0, 2.0, 1.5)), 0.0, 0.01);
}

TEST(PlaneMap, RejectsLinesCornersAndEmptySpace) {
  const PlaneMap map(Scene(0.0));
  lidar::Plane plane;
  EXPECT_FALSE(map.FindPlane(Eigen::Vector3d(5.0, 3.0, 3.0), &plane)) << "pole";
  EXPECT_FALSE(map.FindPlane(Eigen::Vector3d(40.0, 0.0, 0.0), &plane)) << "far from the map";
  // At the foot of the wall the neighbours span both planes: too thick to be one plane.
  PlaneMapOptions strict;
  strict.num_neighbors = 10;
  strict.max_plane_thickness_m = 0.02;
  const PlaneMap strict_map(Scene(0.0), strict);
  EXPECT_FALSE(strict_map.FindPlane(Eigen::Vector3d(19.95, 0.0, 0.05), &plane)) << "corner";
}

}  // namespace
}  // namespace estimation
}  // namespace autocal
