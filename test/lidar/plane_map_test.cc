#include "autocal/lidar/plane_map.h"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/units.h"
#include "autocal/lidar/kd_tree.h"
#include "autocal/lidar/point_cloud.h"
#include "autocal/lidar/voxel_grid.h"

namespace autocal {
namespace lidar {
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
  geometry::Plane plane;
  ASSERT_TRUE(map.FindPlane(Eigen::Vector3d(7.3, -1.2, 0.05), &plane));
  EXPECT_GT(std::abs(plane.normal.z()), 0.999);
  EXPECT_NEAR(plane.SignedDistance(Eigen::Vector3d(7.3, -1.2, 0.0)), 0.0, 0.01);
  ASSERT_TRUE(map.FindPlane(Eigen::Vector3d(19.9, 2.0, 1.5), &plane));
  EXPECT_GT(std::abs(plane.normal.x()), 0.999);
  EXPECT_NEAR(plane.SignedDistance(Eigen::Vector3d(20.0, 2.0, 1.5)), 0.0, 0.01);
}

TEST(PlaneMap, RejectsLinesCornersAndEmptySpace) {
  const PlaneMap map(Scene(0.0));
  geometry::Plane plane;
  EXPECT_FALSE(map.FindPlane(Eigen::Vector3d(5.0, 3.0, 3.0), &plane)) << "pole";
  EXPECT_FALSE(map.FindPlane(Eigen::Vector3d(40.0, 0.0, 0.0), &plane)) << "far from the map";
  // At the foot of the wall the neighbours span both planes: too thick to be one plane.
  PlaneMapOptions strict;
  strict.num_neighbors = 10;
  strict.max_plane_thickness_m = 0.02;
  const PlaneMap strict_map(Scene(0.0), strict);
  EXPECT_FALSE(strict_map.FindPlane(Eigen::Vector3d(19.95, 0.0, 0.05), &plane)) << "corner";
}

// The TLS plane of the k nearest map points computed the plain way, with heap-allocated
// neighbourhoods and the iterative eigen-solver, its normal facing the origin: the reference
// the stack-buffered FindPlane, which mostly takes the closed-form solution, must reproduce.
bool ReferencePlane(const KdTree& tree, const PlaneMapOptions& o, const Eigen::Vector3d& q,
                    geometry::Plane* plane) {
  const std::vector<Neighbor> nn = tree.Knn(q, o.num_neighbors);
  if (static_cast<int>(nn.size()) < o.num_neighbors) return false;
  if (nn.back().squared_distance_m2 > o.max_neighbor_distance_m * o.max_neighbor_distance_m) {
    return false;
  }
  Eigen::Matrix3Xd local(3, o.num_neighbors);
  for (int i = 0; i < o.num_neighbors; ++i) {
    local.col(i) = tree.points().col(nn[static_cast<size_t>(i)].index);
  }
  const Eigen::Vector3d centroid = local.rowwise().mean();
  const Eigen::Matrix3Xd centered = local.colwise() - centroid;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(centered * centered.transpose());
  const Eigen::Vector3d l = solver.eigenvalues();
  if (l(2) <= 0.0 || l(1) < o.min_spread_ratio * l(2)) return false;
  if ((l(1) - l(0)) < o.min_flatness * l(1)) return false;
  plane->normal = solver.eigenvectors().col(0);
  if ((plane->normal.transpose() * centered).cwiseAbs().maxCoeff() > o.max_plane_thickness_m) {
    return false;
  }
  if (plane->normal.dot(centroid) > 0.0) plane->normal = -plane->normal;
  plane->d = -plane->normal.dot(centroid);
  return true;
}

TEST(PlaneMap, MatchesTheReferenceFitEverywhere) {
  const Eigen::Matrix3Xd scene = Scene(0.01);
  PointCloud cloud;
  cloud.points = scene;
  const KdTree tree(VoxelDownsample(cloud, PlaneMapOptions().voxel_m).points);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> x(-1.0, 22.0), y(-6.0, 6.0), z(-0.5, 4.5);
  for (int k : {3, 5, 10, PlaneMap::kMaxNeighbors}) {
    PlaneMapOptions options;
    options.num_neighbors = k;
    const PlaneMap map(scene, options);
    int found = 0;
    for (int trial = 0; trial < 2000; ++trial) {
      const Eigen::Vector3d q(x(rng), y(rng), z(rng));
      geometry::Plane plane, reference;
      const bool ok = map.FindPlane(q, &plane);
      ASSERT_EQ(ok, ReferencePlane(tree, options, q, &reference))
          << "k " << k << " at " << q.transpose();
      if (!ok) continue;
      ++found;
      EXPECT_NEAR(plane.normal.dot(reference.normal), 1.0, 1e-12);
      EXPECT_NEAR(plane.d, reference.d, 1e-12);
    }
    EXPECT_GT(found, 200) << "k " << k;  // the comparison must cover accepted planes
  }
}

// Rings of a 30-beam scanner (0.7 deg apart) over the ground and a wall: far from the sensor
// the nearest map points of a query lie on one ring, a line that FitLocalPlane rejects before its
// iterative solver (PlaneMap::kGateMargin). The decisions and planes must stay the reference's.
TEST(PlaneMap, RejectsRingLinesLikeTheReference) {
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.01);
  std::vector<Eigen::Vector3d> points;
  for (int beam = 0; beam < 30; ++beam) {
    const double elevation = (-15.0 + 0.7 * beam) * kDegToRad;
    for (double azimuth = -M_PI; azimuth < M_PI; azimuth += 0.2 * kDegToRad) {
      const Eigen::Vector3d ray(std::cos(elevation) * std::cos(azimuth),
                                std::cos(elevation) * std::sin(azimuth), std::sin(elevation));
      // The ground 1.8 m below the sensor, a wall at x = 25 m, else nothing.
      double range = ray.z() < 0.0 ? -1.8 / ray.z() : 1e9;
      if (ray.x() > 0.0) range = std::min(range, 25.0 / ray.x());
      if (range > 80.0) continue;
      points.push_back(range * ray + Eigen::Vector3d(noise(rng), noise(rng), noise(rng)));
    }
  }
  Eigen::Matrix3Xd scene(3, static_cast<Eigen::Index>(points.size()));
  for (size_t i = 0; i < points.size(); ++i) scene.col(static_cast<Eigen::Index>(i)) = points[i];
  PointCloud cloud;
  cloud.points = scene;
  const PlaneMapOptions options;
  const KdTree tree(VoxelDownsample(cloud, options.voxel_m).points);
  const PlaneMap map(scene, options);
  // Queries near the scene's points.
  std::uniform_int_distribution<Eigen::Index> pick(0, scene.cols() - 1);
  std::normal_distribution<double> offset(0.0, 0.05);
  int found = 0, lines = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    const Eigen::Vector3d q =
        scene.col(pick(rng)) + Eigen::Vector3d(offset(rng), offset(rng), offset(rng));
    geometry::Plane plane, reference;
    const bool ok = map.FindPlane(q, &plane);
    ASSERT_EQ(ok, ReferencePlane(tree, options, q, &reference)) << "at " << q.transpose();
    if (ok) {
      ++found;
      EXPECT_NEAR(plane.normal.dot(reference.normal), 1.0, 1e-12);
      EXPECT_NEAR(plane.d, reference.d, 1e-12);
      continue;
    }
    // A rejected neighbourhood of k points within reach: count the lines among them.
    const std::vector<Neighbor> nn = tree.Knn(q, options.num_neighbors);
    if (nn.back().squared_distance_m2 >
        options.max_neighbor_distance_m * options.max_neighbor_distance_m) {
      continue;
    }
    Eigen::Matrix3Xd local(3, options.num_neighbors);
    for (int i = 0; i < options.num_neighbors; ++i) {
      local.col(i) = tree.points().col(nn[static_cast<size_t>(i)].index);
    }
    const Eigen::Matrix3Xd centered = local.colwise() - local.rowwise().mean();
    const Eigen::Vector3d l =
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(centered * centered.transpose())
            .eigenvalues();
    if (l(1) < options.min_spread_ratio * l(2)) ++lines;
  }
  // Both kinds of answer must be covered.
  EXPECT_GT(found, 200);
  EXPECT_GT(lines, 200);
}

// The closed-form eigenvalues that reject before the iterative solver are within a small
// fraction of kGateMargin of the solver's, also for lines, blobs and nearly equal eigenvalues.
TEST(PlaneMap, ClosedFormEigenvaluesAreWithinTheGateMargin) {
  std::mt19937 rng(11);
  std::normal_distribution<double> n(0.0, 1.0);
  double worst = 0.0;
  for (int trial = 0; trial < 20000; ++trial) {
    // Five points with axis scales from 1e-4 (a line, a plane) to 1 (a blob), random rotation.
    const Eigen::Vector3d scale(std::pow(10.0, -4.0 * (trial % 5) / 4.0),
                                std::pow(10.0, -4.0 * (trial % 3) / 2.0), 1.0);
    const Eigen::Matrix3d rotation =
        Eigen::Quaterniond(Eigen::Vector4d(n(rng), n(rng), n(rng), n(rng)))
            .normalized()
            .toRotationMatrix();
    Eigen::Matrix3Xd local(3, 5);
    for (int i = 0; i < 5; ++i) {
      local.col(i) = 30.0 * Eigen::Vector3d::Ones() +
                     rotation * scale.cwiseProduct(Eigen::Vector3d(n(rng), n(rng), n(rng)));
    }
    const Eigen::Matrix3Xd centered = local.colwise() - local.rowwise().mean();
    const Eigen::Matrix3d scatter = centered * centered.transpose();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> direct;
    direct.computeDirect(scatter, Eigen::EigenvaluesOnly);
    const Eigen::Vector3d l = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(scatter).eigenvalues();
    worst = std::max(worst, (direct.eigenvalues() - l).cwiseAbs().maxCoeff() / l(2));
  }
  EXPECT_LT(worst, 1e-2 * PlaneMap::kGateMargin);
}

TEST(PlaneMap, RejectsNeighbourCountsOutsideTheBuffer) {
  PlaneMapOptions options;
  options.num_neighbors = 2;
  EXPECT_THROW(PlaneMap(Scene(0.0), options), Error);
  options.num_neighbors = PlaneMap::kMaxNeighbors + 1;
  EXPECT_THROW(PlaneMap(Scene(0.0), options), Error);
}

}  // namespace
}  // namespace lidar
}  // namespace autocal
