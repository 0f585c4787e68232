#include "autocal/lidar/neighbor_grid.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>

#include "autocal/common/error.h"
#include "lidar/nearest_list.h"

namespace autocal {
namespace lidar {

NeighborGrid::NeighborGrid(const Eigen::Matrix3Xd& points, double radius_m) {
  if (!(radius_m > 0.0) || !std::isfinite(radius_m)) {
    throw Error("NeighborGrid: the radius must be positive and finite, got " +
                std::to_string(radius_m) + " m");
  }
  if (points.cols() > std::numeric_limits<int>::max()) {
    throw Error("NeighborGrid: too many points (" + std::to_string(points.cols()) + ")");
  }
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    if (!points.col(i).allFinite()) {
      throw Error("NeighborGrid: point " + std::to_string(i) + " has a non-finite coordinate");
    }
  }
  radius_m_ = radius_m;
  // A hair above the radius: two points within the radius then fall in neighbouring columns
  // despite the rounding of (coordinate - origin) / edge.
  edge_m_ = radius_m * (1.0 + 1e-6);
  const int n = static_cast<int>(points.cols());
  if (n == 0) {
    inverse_edge_ = 1.0 / edge_m_;
    return;
  }
  origin_x_ = points.row(0).minCoeff();
  origin_y_ = points.row(1).minCoeff();
  const double extent_x = points.row(0).maxCoeff() - origin_x_;
  const double extent_y = points.row(1).maxCoeff() - origin_y_;
  while ((std::floor(extent_x / edge_m_) + 1.0) * (std::floor(extent_y / edge_m_) + 1.0) >
         static_cast<double>(kMaxColumns)) {
    edge_m_ *= 2.0;
  }
  inverse_edge_ = 1.0 / edge_m_;
  columns_x_ = static_cast<int>(extent_x * inverse_edge_) + 1;
  columns_y_ = static_cast<int>(extent_y * inverse_edge_) + 1;

  // Counting sort by column; within a column the points keep their order.
  std::vector<int> column_of(static_cast<size_t>(n));
  column_begin_.assign(static_cast<size_t>(columns_x_) * static_cast<size_t>(columns_y_) + 1, 0);
  for (int i = 0; i < n; ++i) {
    const int ix =
        std::min(static_cast<int>((points(0, i) - origin_x_) * inverse_edge_), columns_x_ - 1);
    const int iy =
        std::min(static_cast<int>((points(1, i) - origin_y_) * inverse_edge_), columns_y_ - 1);
    const int c = ix * columns_y_ + iy;
    column_of[static_cast<size_t>(i)] = c;
    ++column_begin_[static_cast<size_t>(c) + 1];
  }
  for (size_t c = 1; c < column_begin_.size(); ++c) column_begin_[c] += column_begin_[c - 1];
  std::vector<int> next(column_begin_.begin(), column_begin_.end() - 1);
  x_.resize(static_cast<size_t>(n));
  y_.resize(static_cast<size_t>(n));
  z_.resize(static_cast<size_t>(n));
  index_.resize(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) {
    int& next_slot = next[static_cast<size_t>(column_of[static_cast<size_t>(i)])];
    const size_t slot = static_cast<size_t>(next_slot++);
    x_[slot] = points(0, i);
    y_[slot] = points(1, i);
    z_[slot] = points(2, i);
    index_[slot] = i;
  }
}

int NeighborGrid::Knn(const Eigen::Vector3d& query, int k, Neighbor* out, double* points) const {
  if (k <= 0 || index_.empty()) return 0;
  const double vx = (query.x() - origin_x_) * inverse_edge_;
  const double vy = (query.y() - origin_y_) * inverse_edge_;
  // Columns beyond the grid by more than one hold nothing within the radius (also rejects
  // non-finite and huge coordinates before the conversion to int).
  if (!(vx >= -1.0 && vx < columns_x_ + 1.0 && vy >= -1.0 && vy < columns_y_ + 1.0) ||
      !std::isfinite(query.z())) {
    return 0;
  }
  // floor(v) for v >= -1, without a call to floor().
  const int cx = static_cast<int>(vx + 1.0) - 1;
  const int cy = static_cast<int>(vy + 1.0) - 1;
  const int x_begin = std::max(cx - 1, 0), x_end = std::min(cx + 1, columns_x_ - 1);
  const int y_begin = std::max(cy - 1, 0), y_end = std::min(cy + 1, columns_y_ - 1);
  if (x_begin > x_end || y_begin > y_end) return 0;

  // Slots (positions in the sorted arrays) of the neighbours found, on the stack for the
  // usual k.
  constexpr int kStackNeighbors = 32;
  std::array<int, kStackNeighbors> stack_slots;
  std::vector<int> heap_slots;
  int* slots = stack_slots.data();
  if (k > kStackNeighbors) {
    heap_slots.resize(static_cast<size_t>(k));
    slots = heap_slots.data();
  }
  const double qx = query.x(), qy = query.y(), qz = query.z();
  const double radius2 = radius_m_ * radius_m_;
  constexpr int kChunk = 64;
  std::array<double, kChunk> candidate_d;
  std::array<int, kChunk> candidate_slot;
  int count = 0;
  for (int x = x_begin; x <= x_end; ++x) {
    const size_t row = static_cast<size_t>(x) * static_cast<size_t>(columns_y_);
    const int begin = column_begin_[row + static_cast<size_t>(y_begin)];
    const int end = column_begin_[row + static_cast<size_t>(y_end) + 1];
    for (int chunk = begin; chunk < end; chunk += kChunk) {
      // The points of a chunk within the radius, gathered without a branch per point: about a
      // sixth of the points scanned pass, in no predictable pattern.
      const int chunk_end = std::min(chunk + kChunk, end);
      int within = 0;
      for (int s = chunk; s < chunk_end; ++s) {
        const size_t u = static_cast<size_t>(s);
        const double dx = qx - x_[u];
        const double dy = qy - y_[u];
        const double dz = qz - z_[u];
        const double d = dx * dx + dy * dy + dz * dz;
        candidate_d[static_cast<size_t>(within)] = d;
        candidate_slot[static_cast<size_t>(within)] = s;
        within += d <= radius2;
      }
      for (int c = 0; c < within; ++c) {
        const double d = candidate_d[static_cast<size_t>(c)];
        const int s = candidate_slot[static_cast<size_t>(c)];
        internal::OfferNearest(k, d, index_[static_cast<size_t>(s)], s, out, slots, &count);
      }
    }
  }
  if (points != nullptr) {
    for (int i = 0; i < count; ++i) {
      const size_t u = static_cast<size_t>(slots[i]);
      points[3 * i] = x_[u];
      points[3 * i + 1] = y_[u];
      points[3 * i + 2] = z_[u];
    }
  }
  return count;
}

}  // namespace lidar
}  // namespace autocal
