#pragma once

// Nearest-neighbour search over a fixed set of 3D points: a k-d tree built once, queried
// many times. Results are exact: every query returns what a brute-force scan sorted by
// (squared distance, index) would, so ties go to the lower index.

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <vector>

#include "autocal/lidar/neighbor.h"

namespace autocal {
namespace lidar {

class KdTree {
 public:
  // Copies (or moves) the points in and builds the tree, its top levels on up to
  // num_threads threads (the tree does not depend on the count). Throws autocal::Error on a
  // non-finite point or num_threads < 1.
  explicit KdTree(Eigen::Matrix3Xd points, int num_threads = 1);
  ~KdTree();
  KdTree(KdTree&&) noexcept;
  KdTree& operator=(KdTree&&) noexcept;
  KdTree(const KdTree&) = delete;
  KdTree& operator=(const KdTree&) = delete;

  int64_t size() const;
  const Eigen::Matrix3Xd& points() const;

  // The nearest point strictly closer than max_distance_m (pass infinity for no bound;
  // ties: the lower index). Returns false when there is none. The bound prunes the search,
  // so a tight bound is faster.
  bool Nearest(const Eigen::Vector3d& query, double max_distance_m, Neighbor* nearest) const;

  // The k nearest points, closest first (ties: lower index first), into
  // out[0 .. returned count). out must have room for k entries. Returns min(k, size()).
  int Knn(const Eigen::Vector3d& query, int k, Neighbor* out) const;
  std::vector<Neighbor> Knn(const Eigen::Vector3d& query, int k) const;
  // The same among the points no farther than max_distance_m: returns how many there are (at
  // most k). The bound prunes the search: a query whose k-th neighbour lies beyond it ends
  // early (the plane maps reject those anyway).
  int Knn(const Eigen::Vector3d& query, int k, double max_distance_m, Neighbor* out) const;
  // The same, and the neighbours' coordinates: out[i]'s point into points[3 i .. 3 i + 3)
  // (room for 3 k doubles; a 3 x k column-major matrix). Faster than reading points() by
  // index, which misses the cache where the search has just read the tree's own copy.
  int Knn(const Eigen::Vector3d& query, int k, double max_distance_m, Neighbor* out,
          double* points) const;

  // Every point strictly closer than radius_m, closest first (ties: lower index first).
  // `neighbors` is cleared first; reuse it across calls to avoid allocations.
  void RadiusSearch(const Eigen::Vector3d& query, double radius_m,
                    std::vector<Neighbor>* neighbors) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace lidar
}  // namespace autocal
