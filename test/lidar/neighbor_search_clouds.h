#pragma once

// Point clouds that exercise a nearest-neighbour search (KdTree, NeighborGrid): uniform,
// scan-like density, and clouds whose distances tie.

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <random>

namespace autocal {
namespace test {

// n points uniform in the box [-extent_m, extent_m].
inline Eigen::Matrix3Xd UniformPoints(int n, uint64_t seed, const Eigen::Vector3d& extent_m) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::Matrix3Xd points(3, n);
  for (int i = 0; i < n; ++i) {
    points.col(i) = Eigen::Vector3d(u(rng), u(rng), u(rng)).cwiseProduct(extent_m);
  }
  return points;
}

// Scan-like density: most of the n points near the origin, a few far away (uneven cells).
inline Eigen::Matrix3Xd ScanLikePoints(int n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  Eigen::Matrix3Xd scan(3, n);
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d direction(gauss(rng), gauss(rng), 0.1 * gauss(rng));
    scan.col(i) = std::exp(3.0 * std::abs(gauss(rng))) * direction.normalized();
  }
  return scan;
}

// 40 distinct points repeated 50 times each, so distances tie.
inline Eigen::Matrix3Xd DuplicatedPoints() {
  const Eigen::Matrix3Xd distinct = UniformPoints(40, 11, Eigen::Vector3d(5.0, 5.0, 5.0));
  Eigen::Matrix3Xd duplicates(3, 2000);
  for (int i = 0; i < duplicates.cols(); ++i) duplicates.col(i) = distinct.col((7 * i) % 40);
  return duplicates;
}

// A planar 40 x 40 integer lattice: a query at a lattice point ties with 4 neighbours at 1 m.
inline Eigen::Matrix3Xd IntegerLattice() {
  Eigen::Matrix3Xd lattice(3, 1600);
  for (int i = 0; i < lattice.cols(); ++i) lattice.col(i) = Eigen::Vector3d(i % 40, i / 40, 0.0);
  return lattice;
}

}  // namespace test
}  // namespace autocal
