#include "autocal/lidar/plane_map.h"

#include <Eigen/Eigenvalues>
#include <array>
#include <cmath>
#include <string>

#include "autocal/common/error.h"
#include "autocal/lidar/point_cloud.h"
#include "autocal/lidar/voxel_grid.h"

namespace autocal {
namespace lidar {

namespace {

const PlaneMapOptions& Checked(const PlaneMapOptions& options) {
  if (options.num_neighbors < 3 || options.num_neighbors > PlaneMap::kMaxNeighbors) {
    throw Error("PlaneMap: num_neighbors must be in [3, " +
                std::to_string(PlaneMap::kMaxNeighbors) + "], got " +
                std::to_string(options.num_neighbors));
  }
  if (!(options.max_neighbor_distance_m > 0.0) || !std::isfinite(options.max_neighbor_distance_m)) {
    throw Error("PlaneMap: max_neighbor_distance_m must be positive and finite, got " +
                std::to_string(options.max_neighbor_distance_m));
  }
  return options;
}

Eigen::Matrix3Xd Downsample(const Eigen::Matrix3Xd& points, double voxel_m) {
  PointCloud cloud;
  cloud.points = points;
  return VoxelDownsample(cloud, voxel_m).points;
}

}  // namespace

PlaneMap::PlaneMap(const Eigen::Matrix3Xd& points_W, const PlaneMapOptions& options)
    : options_(Checked(options)),
      grid_(Downsample(points_W, options.voxel_m), options.max_neighbor_distance_m) {}

bool PlaneMap::FindPlane(const Eigen::Vector3d& p_W, geometry::Plane* plane) const {
  const int k = options_.num_neighbors;
  // Buffers sized for the usual neighbour counts when they suffice: constructing the
  // kMaxNeighbors entries of the larger one took a fifth of a lookup's own time.
  constexpr int kUsualNeighbors = 8;
  Neighborhood local(3, k);
  const auto fit = [&](Neighbor* neighbors) {
    return grid_.Knn(p_W, k, neighbors, local.data()) == k && FitLocalPlane(local, plane);
  };
  if (k <= kUsualNeighbors) {
    std::array<Neighbor, kUsualNeighbors> neighbors;
    return fit(neighbors.data());
  }
  std::array<Neighbor, kMaxNeighbors> neighbors;
  return fit(neighbors.data());
}

bool PlaneMap::FitLocalPlane(const Neighborhood& local, geometry::Plane* plane) const {
  const Eigen::Vector3d centroid = local.rowwise().mean();
  const Neighborhood centered = local.colwise() - centroid;
  // The scatter's six distinct entries summed point by point (Eigen's product of a dynamic
  // 3 x n block with its transpose went through its general kernel: a ninth of a lookup).
  double sxx = 0.0, sxy = 0.0, sxz = 0.0, syy = 0.0, syz = 0.0, szz = 0.0;
  for (Eigen::Index i = 0; i < centered.cols(); ++i) {
    const double x = centered(0, i), y = centered(1, i), z = centered(2, i);
    sxx += x * x;
    sxy += x * y;
    sxz += x * z;
    syy += y * y;
    syz += y * z;
    szz += z * z;
  }
  Eigen::Matrix3d scatter;
  scatter << sxx, sxy, sxz, sxy, syy, syz, sxz, syz, szz;
  // The closed-form eigenvalues decide the gates (line, blob) when both pass or fail by more
  // than kGateMargin of the largest; a neighbourhood nearer a gate goes on to the iterative
  // solver, so that the decision is the solver's. Past both gates the normal is the kernel of
  // S - l0 I: l0 is simple (l1 - l0 >= min_flatness l1), so the rows of S - l0 I span the plane
  // orthogonal to the normal and their largest cross product lies along it, accurate to the
  // rounding times l2 / (l1 - l0) (plane_map_test.cc).
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> direct;
  direct.computeDirect(scatter, Eigen::EigenvaluesOnly);
  const Eigen::Vector3d e = direct.eigenvalues();  // ascending
  const double margin = kGateMargin * e(2);
  const double spread = e(1) - options_.min_spread_ratio * e(2);
  const double flatness = (e(1) - e(0)) - options_.min_flatness * e(1);
  if (e(2) > 0.0 && (spread + margin < 0.0 || flatness + margin < 0.0)) return false;
  Eigen::Vector3d normal;
  if (e(0) >= 0.0 && spread > margin && flatness > margin) {
    Eigen::Matrix3d shifted = scatter;
    shifted.diagonal().array() -= e(0);
    const Eigen::Vector3d c01 = shifted.row(0).cross(shifted.row(1));
    const Eigen::Vector3d c02 = shifted.row(0).cross(shifted.row(2));
    const Eigen::Vector3d c12 = shifted.row(1).cross(shifted.row(2));
    const double n01 = c01.squaredNorm(), n02 = c02.squaredNorm(), n12 = c12.squaredNorm();
    if (n01 >= n02 && n01 >= n12) {
      normal = c01 / std::sqrt(n01);
    } else if (n02 >= n12) {
      normal = c02 / std::sqrt(n02);
    } else {
      normal = c12 / std::sqrt(n12);
    }
  } else {
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(scatter);
    const Eigen::Vector3d l = solver.eigenvalues();                            // ascending
    if (l(2) <= 0.0 || l(1) < options_.min_spread_ratio * l(2)) return false;  // a line
    if ((l(1) - l(0)) < options_.min_flatness * l(1)) return false;            // a blob
    normal = solver.eigenvectors().col(0);
  }
  for (Eigen::Index i = 0; i < centered.cols(); ++i) {
    if (std::abs(normal.dot(centered.col(i))) > options_.max_plane_thickness_m) return false;
  }
  // Either solver's sign is arbitrary: the normal is turned to face the map frame's origin.
  plane->normal = normal.dot(centroid) > 0.0 ? Eigen::Vector3d(-normal) : normal;
  plane->d = -plane->normal.dot(centroid);
  return true;
}

}  // namespace lidar
}  // namespace autocal
