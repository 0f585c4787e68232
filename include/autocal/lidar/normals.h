#pragma once

// Surface normals and planarity by PCA of each point's neighbourhood (docs/lidar.md §2.3).
// For the k nearest neighbours with centroid mu and covariance C = 1/k sum (q - mu)(q - mu)^T
// and eigenvalues l0 <= l1 <= l2, the normal is the eigenvector of l0 and the planarity is
// (l1 - l0) / l2 (eq. 2.3): 1 for a perfect plane, near 0 for a line or an isotropic blob.

#include <Eigen/Core>
#include <cstdint>

#include "autocal/lidar/kd_tree.h"

namespace autocal {
namespace lidar {

struct NormalEstimationOptions {
  // Neighbours per point, the point itself included. 10 is enough on a 0.25 m voxel grid
  // and keeps the neighbourhood local.
  int num_neighbors = 10;
  // Neighbours farther than this are ignored (0 = no bound): a wall and the ground meeting
  // at a corner must not be averaged into one tilted plane.
  double max_radius_m = 0.0;
  // Normals are flipped to face this point (the sensor origin of the cloud's frame).
  Eigen::Vector3d viewpoint = Eigen::Vector3d::Zero();
};

struct SurfaceNormals {
  // Unit normals, one column per point; a zero column where fewer than 3 neighbours were
  // found (no plane defined).
  Eigen::Matrix3Xd normals;
  // (l1 - l0) / l2 per point in [0, 1]; 0 where the normal is undefined.
  Eigen::VectorXd planarity;
};

// Normals of every point of `tree.points()`, searching neighbours in the same tree, on
// num_threads threads (common/parallel_for.h). Throws autocal::Error when
// setting.num_neighbors < 3.
SurfaceNormals EstimateNormals(const KdTree& tree, const NormalEstimationOptions& setting = {},
                               int num_threads = 1);

// The normal (facing setting.viewpoint) and planarity of the single point
// tree.points().col(index), as EstimateNormals computes them. Returns false where the
// normal is undefined (fewer than 3 neighbours within the radius, or coincident points).
bool EstimateNormal(const KdTree& tree, int64_t index, const NormalEstimationOptions& setting,
                    Eigen::Vector3d* normal, double* planarity);

// Normal (unit, sign arbitrary) and planarity of one neighbourhood given as columns.
// Returns false when there are fewer than 3 points or they are all the same point.
bool PcaNormal(const Eigen::Matrix3Xd& neighbourhood, Eigen::Vector3d* normal, double* planarity);

}  // namespace lidar
}  // namespace autocal
