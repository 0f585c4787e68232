#pragma once

// A map of local planes in the world frame for point-to-plane association
// (docs/estimation.md, "Local map and association"): the map points are voxel-downsampled
// and indexed by a grid of columns as wide as the neighbour radius; a query point is
// associated with the total-least-squares plane of its k nearest map points when those points
// are close, flat and thin enough.

#include <Eigen/Core>
#include <cstdint>

#include "autocal/geometry/plane.h"
#include "autocal/lidar/neighbor_grid.h"

namespace autocal {
namespace lidar {

struct PlaneMapOptions {
  double voxel_m = 0.2;  // map resolution
  // Points per local plane, 3 .. PlaneMap::kMaxNeighbors. Fewer sit on one or two scan rings
  // of a sparse LiDAR, whose tilt across the rings is poorly fixed (docs/evaluation.md).
  int num_neighbors = 10;
  double max_neighbor_distance_m = 1.0;  // farthest neighbour accepted
  // With the neighbourhood's covariance eigenvalues l0 <= l1 <= l2: flatness (l1 - l0) / l1
  // is 1 for a plane and 0 for an isotropic blob; l1 / l2 is 0 for points on a line.
  double min_flatness = 0.8;
  // The line gate also rejects strips of one or two scan rings (docs/sliding_window.md,
  // "Planes across scan rings"): a plane fitted to a narrow strip extrapolates the road's
  // curvature to the point, and the error moves with the rings when the body pitches, which
  // the estimators took for a pitch (figures in docs/history/estimation.md).
  double min_spread_ratio = 0.1;
  // Largest distance of any neighbour to the fitted plane: rejects corners and clutter.
  double max_plane_thickness_m = 0.1;
};

class PlaneMap {
 public:
  // The neighbourhood lives in fixed-size buffers on the stack: a query allocates nothing.
  static constexpr int kMaxNeighbors = 32;
  // A neighbourhood whose closed-form covariance eigenvalues fail a gate (line, blob) by more
  // than this fraction of the largest is rejected without the iterative eigen-solver; nearer
  // the gate the solver decides. Far above the closed-form error (plane_map_test.cc).
  static constexpr double kGateMargin = 1e-5;

  // Voxel-downsamples the points (options.voxel_m) into a map. Throws autocal::Error when
  // options.num_neighbors is outside [3, kMaxNeighbors] or max_neighbor_distance_m is not
  // positive and finite.
  PlaneMap(const Eigen::Matrix3Xd& points_W, const PlaneMapOptions& options = {});
  // The local plane around p_W, or false when the neighbourhood is not a clean plane. Its
  // normal faces the map frame's origin (plane->d >= 0). Safe to call from several threads
  // at once.
  bool FindPlane(const Eigen::Vector3d& p_W, geometry::Plane* plane) const;

  int64_t size() const { return grid_.size(); }

 private:
  using Neighborhood = Eigen::Matrix<double, 3, Eigen::Dynamic, Eigen::ColMajor, 3, kMaxNeighbors>;
  bool FitLocalPlane(const Neighborhood& local, geometry::Plane* plane) const;

  PlaneMapOptions options_;
  NeighborGrid grid_;
};

}  // namespace lidar
}  // namespace autocal
