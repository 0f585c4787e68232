#pragma once

// The k nearest neighbours within a radius fixed at construction, over a fixed set of 3D
// points. The points are bucketed into the vertical columns of a square grid in x, y whose
// edge is at least the radius, so that every point within the radius of a query lies in the
// 3 x 3 columns around the query's; the columns are stored x-major, so those nine are three
// contiguous runs of points. For the neighbourhoods of plane association (a few points within
// a metre, in a scan of thousands) this scans a few dozen points where a k-d tree descends
// and backtracks through its nodes. Results are exact and ordered as KdTree's: by (squared
// distance, index), so ties go to the lower index.

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "autocal/lidar/neighbor.h"

namespace autocal {
namespace lidar {

class NeighborGrid {
 public:
  // Grids with more columns than this get a coarser edge (any edge >= the radius is exact).
  static constexpr int64_t kMaxColumns = int64_t{1} << 20;

  // Copies the points in, bucketed. Throws autocal::Error on a non-finite point, on more
  // points than an int counts, or on a radius that is not positive and finite.
  NeighborGrid(const Eigen::Matrix3Xd& points, double radius_m);

  int64_t size() const { return static_cast<int64_t>(index_.size()); }
  double radius_m() const { return radius_m_; }
  // The grid's edge: just above the radius, or a power-of-two multiple of that (kMaxColumns).
  double column_edge_m() const { return edge_m_; }

  // The k nearest points no farther than radius_m() from the query (a bound hit exactly
  // counts), closest first, into out[0 .. returned count), which needs room for k entries;
  // when `points` is not null, also out[i]'s coordinates into points[3 i .. 3 i + 3) (a 3 x k
  // column-major matrix). A query with a non-finite coordinate finds nothing.
  int Knn(const Eigen::Vector3d& query, int k, Neighbor* out, double* points = nullptr) const;

 private:
  double radius_m_ = 0.0;
  double edge_m_ = 0.0;
  double inverse_edge_ = 0.0;
  double origin_x_ = 0.0, origin_y_ = 0.0;
  int columns_x_ = 0, columns_y_ = 0;
  // Points of column c = ix * columns_y_ + iy at [column_begin_[c], column_begin_[c + 1]),
  // coordinates in separate arrays.
  std::vector<int> column_begin_;
  std::vector<double> x_, y_, z_;
  std::vector<int> index_;  // the point's column in the constructor's matrix
};

}  // namespace lidar
}  // namespace autocal
