#include "autocal/lidar/neighbor_grid.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>

#include "autocal/common/error.h"
#include "common/cpu_features.h"

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#endif

namespace autocal {
namespace lidar {

namespace {

// Squared distances from q of the points [begin, end) of the sorted arrays, (dx^2 + dy^2) + dz^2
// in that order; those within radius2 (not NaN) are written, in slot order, to d and slot from
// their start. Returns how many. d and slot hold end - begin + 3 entries.
int GatherWithinPlain(const double* x, const double* y, const double* z, int begin, int end,
                      double qx, double qy, double qz, double radius2, double* d, int* slot) {
  int within = 0;
  for (int s = begin; s < end; ++s) {
    const size_t u = static_cast<size_t>(s);
    const double dx = qx - x[u];
    const double dy = qy - y[u];
    const double dz = qz - z[u];
    const double d2 = dx * dx + dy * dy + dz * dz;
    d[within] = d2;
    slot[within] = s;
    within += d2 <= radius2;
  }
  return within;
}

#if defined(__x86_64__) || defined(__i386__)
// The same, four points at a time: the passing lanes are packed to the front by a permutation
// chosen by their mask (the same operations in the same order, so the same bits).
__attribute__((target("avx2,popcnt"))) int GatherWithinAvx2(const double* x, const double* y,
                                                            const double* z, int begin, int end,
                                                            double qx, double qy, double qz,
                                                            double radius2, double* d, int* slot) {
  // Per mask, the float pairs (one double each) of the passing lanes first.
  alignas(32) static const int kPack[16][8] = {
      {0, 1, 2, 3, 4, 5, 6, 7}, {0, 1, 2, 3, 4, 5, 6, 7}, {2, 3, 0, 1, 4, 5, 6, 7},
      {0, 1, 2, 3, 4, 5, 6, 7}, {4, 5, 0, 1, 2, 3, 6, 7}, {0, 1, 4, 5, 2, 3, 6, 7},
      {2, 3, 4, 5, 0, 1, 6, 7}, {0, 1, 2, 3, 4, 5, 6, 7}, {6, 7, 0, 1, 2, 3, 4, 5},
      {0, 1, 6, 7, 2, 3, 4, 5}, {2, 3, 6, 7, 0, 1, 4, 5}, {0, 1, 2, 3, 6, 7, 4, 5},
      {4, 5, 6, 7, 0, 1, 2, 3}, {0, 1, 4, 5, 6, 7, 2, 3}, {2, 3, 4, 5, 6, 7, 0, 1},
      {0, 1, 2, 3, 4, 5, 6, 7}};
  // The lanes' order by the same permutation, as offsets of their slots.
  alignas(16) static const int kLane[16][4] = {
      {0, 1, 2, 3}, {0, 1, 2, 3}, {1, 0, 2, 3}, {0, 1, 2, 3}, {2, 0, 1, 3}, {0, 2, 1, 3},
      {1, 2, 0, 3}, {0, 1, 2, 3}, {3, 0, 1, 2}, {0, 3, 1, 2}, {1, 3, 0, 2}, {0, 1, 3, 2},
      {2, 3, 0, 1}, {0, 2, 3, 1}, {1, 2, 3, 0}, {0, 1, 2, 3}};
  const __m256d vx = _mm256_set1_pd(qx), vy = _mm256_set1_pd(qy), vz = _mm256_set1_pd(qz);
  const __m256d r2 = _mm256_set1_pd(radius2);
  int within = 0;
  int s = begin;
  for (; s + 4 <= end; s += 4) {
    const __m256d dx = _mm256_sub_pd(vx, _mm256_loadu_pd(x + s));
    const __m256d dy = _mm256_sub_pd(vy, _mm256_loadu_pd(y + s));
    const __m256d dz = _mm256_sub_pd(vz, _mm256_loadu_pd(z + s));
    const __m256d d2 = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(dx, dx), _mm256_mul_pd(dy, dy)),
                                     _mm256_mul_pd(dz, dz));
    const int mask = _mm256_movemask_pd(_mm256_cmp_pd(d2, r2, _CMP_LE_OQ));
    const __m256i pack = _mm256_load_si256(reinterpret_cast<const __m256i*>(kPack[mask]));
    _mm256_storeu_pd(d + within,
                     _mm256_castps_pd(_mm256_permutevar8x32_ps(_mm256_castpd_ps(d2), pack)));
    const __m128i lanes = _mm_load_si128(reinterpret_cast<const __m128i*>(kLane[mask]));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(slot + within),
                     _mm_add_epi32(lanes, _mm_set1_epi32(s)));
    within += __builtin_popcount(static_cast<unsigned>(mask));
  }
  return within +
         GatherWithinPlain(x, y, z, s, end, qx, qy, qz, radius2, d + within, slot + within);
}
#endif

int GatherWithin(const double* x, const double* y, const double* z, int begin, int end, double qx,
                 double qy, double qz, double radius2, double* d, int* slot) {
#if defined(__x86_64__) || defined(__i386__)
  if (autocal::internal::CpuHasAvx2()) {
    return GatherWithinAvx2(x, y, z, begin, end, qx, qy, qz, radius2, d, slot);
  }
#endif
  return GatherWithinPlain(x, y, z, begin, end, qx, qy, qz, radius2, d, slot);
}

}  // namespace

NeighborGrid::NeighborGrid(const Eigen::Matrix3Xd& points, double radius_m) {
  // A subnormal radius has an infinite inverse: 0 * inf would make a NaN column index.
  if (!(radius_m > 0.0) || !std::isfinite(radius_m) || !std::isfinite(1.0 / radius_m)) {
    throw Error("NeighborGrid: the radius must be positive, finite and not subnormal, got " +
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
  // Finite points near +-1e308 can still span an infinite extent: no grid of columns covers it
  // (the loop below would never end and the column counts would not fit an int).
  if (!std::isfinite(extent_x) || !std::isfinite(extent_y)) {
    throw Error("NeighborGrid: the points span more than the range of a double");
  }
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

  // The neighbours found, closest first: their squared distances and slots (positions in the
  // sorted arrays), on the stack for the usual k. A candidate's index, which breaks ties, is
  // read only on a tie.
  constexpr int kStackNeighbors = 32;
  std::array<double, kStackNeighbors> stack_d;
  std::array<int, kStackNeighbors> stack_slots;
  std::vector<double> heap_d;
  std::vector<int> heap_slots;
  double* best_d = stack_d.data();
  int* slots = stack_slots.data();
  if (k > kStackNeighbors) {
    heap_d.resize(static_cast<size_t>(k));
    heap_slots.resize(static_cast<size_t>(k));
    best_d = heap_d.data();
    slots = heap_slots.data();
  }
  const int* index = index_.data();
  // Whether (d, slot s) comes before place i: by distance, a tie by the lower index.
  const auto before = [&](double d, int s, int i) {
    return d < best_d[i] || (d == best_d[i] && index[s] < index[slots[i]]);
  };
  const double qx = query.x(), qy = query.y(), qz = query.z();
  const double radius2 = radius_m_ * radius_m_;
  constexpr int kChunk = 64;
  std::array<double, kChunk + 3> candidate_d;
  std::array<int, kChunk + 3> candidate_slot;
  int count = 0;
  for (int x = x_begin; x <= x_end; ++x) {
    const size_t row = static_cast<size_t>(x) * static_cast<size_t>(columns_y_);
    const int begin = column_begin_[row + static_cast<size_t>(y_begin)];
    const int end = column_begin_[row + static_cast<size_t>(y_end) + 1];
    for (int chunk = begin; chunk < end; chunk += kChunk) {
      // The points of a chunk within the radius, gathered without a branch per point: about a
      // sixth of the points scanned pass, in no predictable pattern.
      const int within =
          GatherWithin(x_.data(), y_.data(), z_.data(), chunk, std::min(chunk + kChunk, end), qx,
                       qy, qz, radius2, candidate_d.data(), candidate_slot.data());
      for (int c = 0; c < within; ++c) {
        const double d = candidate_d[static_cast<size_t>(c)];
        const int s = candidate_slot[static_cast<size_t>(c)];
        int i;
        if (count < k) {
          i = count++;
        } else if (before(d, s, k - 1)) {
          i = k - 1;
        } else {
          continue;
        }
        for (; i > 0 && before(d, s, i - 1); --i) {
          best_d[i] = best_d[i - 1];
          slots[i] = slots[i - 1];
        }
        best_d[i] = d;
        slots[i] = s;
      }
    }
  }
  for (int i = 0; i < count; ++i) {
    out[i] = Neighbor{index[slots[i]], best_d[i]};
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
