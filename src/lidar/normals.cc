#include "autocal/lidar/normals.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <limits>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/parallel_for.h"

namespace autocal {
namespace lidar {
namespace {

// Normal and planarity from the accumulated first and second moments of a neighbourhood.
bool NormalFromMoments(const Eigen::Vector3d& sum, const Eigen::Matrix3d& sum_outer, int count,
                       Eigen::Vector3d* normal, double* planarity) {
  if (count < 3) return false;
  const double inv = 1.0 / count;
  const Eigen::Vector3d mean = sum * inv;
  const Eigen::Matrix3d covariance = sum_outer * inv - mean * mean.transpose();
  // computeDirect is the closed-form 3x3 solver: an order of magnitude faster than the
  // iterative one and accurate enough for the smallest eigenvector of a centred covariance.
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver;
  solver.computeDirect(covariance);
  const Eigen::Vector3d l = solver.eigenvalues().cwiseMax(0.0);  // ascending
  if (!(l(2) > 0.0)) return false;
  *normal = solver.eigenvectors().col(0).normalized();
  *planarity = (l(1) - l(0)) / l(2);
  return true;
}

}  // namespace

bool PcaNormal(const Eigen::Matrix3Xd& neighbourhood, Eigen::Vector3d* normal, double* planarity) {
  const int count = static_cast<int>(neighbourhood.cols());
  if (count < 3) return false;
  // Centre on the first point before accumulating so that far-away clouds keep precision.
  const Eigen::Vector3d origin = neighbourhood.col(0);
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  Eigen::Matrix3d sum_outer = Eigen::Matrix3d::Zero();
  for (int i = 0; i < count; ++i) {
    const Eigen::Vector3d q = neighbourhood.col(i) - origin;
    sum += q;
    sum_outer += q * q.transpose();
  }
  return NormalFromMoments(sum, sum_outer, count, normal, planarity);
}

namespace {

void RequireNeighbors(const NormalEstimationOptions& setting) {
  if (setting.num_neighbors < 3) {
    throw Error("EstimateNormals: num_neighbors must be at least 3, got " +
                std::to_string(setting.num_neighbors));
  }
}

// EstimateNormal with the caller's scratch space for the neighbours.
bool NormalOfPoint(const KdTree& tree, int64_t index, const NormalEstimationOptions& setting,
                   Neighbor* neighbors, Eigen::Vector3d* normal, double* planarity) {
  const Eigen::Matrix3Xd& points = tree.points();
  const double max_sq = setting.max_radius_m > 0.0 ? setting.max_radius_m * setting.max_radius_m
                                                   : std::numeric_limits<double>::infinity();
  const Eigen::Vector3d p = points.col(index);
  const int found = tree.Knn(p, setting.num_neighbors, neighbors);
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  Eigen::Matrix3d sum_outer = Eigen::Matrix3d::Zero();
  int count = 0;
  for (int j = 0; j < found; ++j) {
    if (neighbors[j].squared_distance_m2 > max_sq) break;  // sorted, closest first
    const Eigen::Vector3d q = points.col(neighbors[j].index) - p;
    sum += q;
    sum_outer.noalias() += q * q.transpose();
    ++count;
  }
  if (!NormalFromMoments(sum, sum_outer, count, normal, planarity)) return false;
  if (normal->dot(setting.viewpoint - p) < 0.0) *normal = -*normal;
  return true;
}

}  // namespace

bool EstimateNormal(const KdTree& tree, int64_t index, const NormalEstimationOptions& setting,
                    Eigen::Vector3d* normal, double* planarity) {
  RequireNeighbors(setting);
  constexpr int kStackNeighbors = 32;
  if (setting.num_neighbors <= kStackNeighbors) {
    std::array<Neighbor, kStackNeighbors> neighbors;
    return NormalOfPoint(tree, index, setting, neighbors.data(), normal, planarity);
  }
  std::vector<Neighbor> neighbors(static_cast<size_t>(setting.num_neighbors));
  return NormalOfPoint(tree, index, setting, neighbors.data(), normal, planarity);
}

SurfaceNormals EstimateNormals(const KdTree& tree, const NormalEstimationOptions& setting,
                               int num_threads) {
  RequireNeighbors(setting);
  const int64_t n = tree.size();
  SurfaceNormals out;
  out.normals.setZero(3, n);
  out.planarity.setZero(n);
  ParallelFor(0, n, num_threads, [&](int64_t begin, int64_t end, int /*chunk*/) {
    std::vector<Neighbor> neighbors(static_cast<size_t>(setting.num_neighbors));
    Eigen::Vector3d normal;
    double planarity = 0.0;
    for (int64_t i = begin; i < end; ++i) {
      if (!NormalOfPoint(tree, i, setting, neighbors.data(), &normal, &planarity)) continue;
      out.normals.col(i) = normal;
      out.planarity(i) = planarity;
    }
  });
  return out;
}

}  // namespace lidar
}  // namespace autocal
