#include "autocal/lidar/kd_tree.h"

#include <algorithm>
#include <array>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>

#include "autocal/common/error.h"
#include "autocal/common/parallel_for.h"
#include "lidar/nearest_list.h"

namespace autocal {
namespace lidar {
namespace {

// A cell holds at most this many points unless they are all equal.
constexpr int kLeafMaxSize = 24;
// Subtrees of fewer points are built on one thread: a fork costs more than they take.
constexpr int kMinParallelBuild = 4096;

// A point copied into the tree's own order: the points of a leaf are contiguous, so a leaf
// scan reads consecutive memory. `index` is the column in KdTree::points().
struct TreePoint {
  std::array<double, 3> xyz;
  int index;
};

// Internal node (dim >= 0): the left child follows it in the node vector, `right_or_begin`
// is the index of the right child; `left_max` is the largest coordinate of the left child's points
// along `dim`, `right_min` the smallest of the right child's (left_max <= right_min).
// Leaf (dim < 0): its points are tree points [begin, end).
struct Node {
  double left_max = 0.0;
  double right_min = 0.0;
  int right_or_begin = 0;
  int end = 0;
  int dim = -1;
};

struct Box {
  std::array<double, 3> min;
  std::array<double, 3> max;
};

// Two interleaved running boxes halve the dependency chains of min and max.
Box BoundsOf(const TreePoint* begin, const TreePoint* end) {
  Box a{begin->xyz, begin->xyz};
  Box b = a;
  const TreePoint* p = begin + 1;
  for (; p + 1 < end; p += 2) {
    for (int d = 0; d < 3; ++d) {
      a.min[d] = std::min(a.min[d], p[0].xyz[d]);
      a.max[d] = std::max(a.max[d], p[0].xyz[d]);
      b.min[d] = std::min(b.min[d], p[1].xyz[d]);
      b.max[d] = std::max(b.max[d], p[1].xyz[d]);
    }
  }
  for (; p < end; ++p) {
    for (int d = 0; d < 3; ++d) {
      a.min[d] = std::min(a.min[d], p->xyz[d]);
      a.max[d] = std::max(a.max[d], p->xyz[d]);
    }
  }
  for (int d = 0; d < 3; ++d) {
    a.min[d] = std::min(a.min[d], b.min[d]);
    a.max[d] = std::max(a.max[d], b.max[d]);
  }
  return a;
}

// Moves the points with coordinate `dim` below `cut` to the front of [first, last) and
// returns the end of them. Which side a point falls on is unpredictable, so branches on it
// would be mispredicted half the time: as in BlockQuicksort (Edelkamp & Weiss 2016), blocks
// at both ends are first classified without branches into lists of misplaced points, then
// misplaced pairs are swapped.
TreePoint* PartitionBelow(TreePoint* first, TreePoint* last, int dim, double cut) {
  constexpr int kBlock = 64;
  std::array<uint8_t, kBlock> left_misplaced;   // offsets from first of points >= cut
  std::array<uint8_t, kBlock> right_misplaced;  // offsets back from last - 1 of points < cut
  int left_count = 0, left_start = 0, right_count = 0, right_start = 0;
  while (last - first >= 2 * kBlock) {
    if (left_count == 0) {
      left_start = 0;
      for (int i = 0; i < kBlock; ++i) {
        left_misplaced[static_cast<size_t>(left_count)] = static_cast<uint8_t>(i);
        left_count += !(first[i].xyz[dim] < cut);
      }
    }
    if (right_count == 0) {
      right_start = 0;
      for (int i = 0; i < kBlock; ++i) {
        right_misplaced[static_cast<size_t>(right_count)] = static_cast<uint8_t>(i);
        right_count += last[-1 - i].xyz[dim] < cut;
      }
    }
    const int swaps = std::min(left_count, right_count);
    for (int j = 0; j < swaps; ++j) {
      std::swap(first[left_misplaced[static_cast<size_t>(left_start + j)]],
                last[-1 - right_misplaced[static_cast<size_t>(right_start + j)]]);
    }
    left_count -= swaps;
    right_count -= swaps;
    left_start += swaps;
    right_start += swaps;
    if (left_count == 0) first += kBlock;
    if (right_count == 0) last -= kBlock;
  }
  // Fewer than 2 kBlock points are left: write each to both free ends of a buffer, advancing
  // only the end it belongs to (the other write is overwritten later), and copy back.
  std::array<TreePoint, 2 * kBlock> buffer;
  int below_count = 0;
  int above_begin = static_cast<int>(last - first);
  for (const TreePoint* p = first; p < last; ++p) {
    const bool below = p->xyz[dim] < cut;
    buffer[static_cast<size_t>(below_count)] = *p;
    buffer[static_cast<size_t>(above_begin - 1)] = *p;
    below_count += below;
    above_begin -= !below;
  }
  std::copy(buffer.begin(), buffer.begin() + (last - first), first);
  return first + below_count;
}

// Squared distance, summed in the order x, y, z. The search bounds (Offsets::Sum) add the
// per-axis terms in the same order, so rounding keeps bound <= distance and the pruning
// tests below are exact.
double SquaredDistance(const double* query, const std::array<double, 3>& p) {
  const double dx = query[0] - p[0];
  const double dy = query[1] - p[1];
  const double dz = query[2] - p[2];
  return dx * dx + dy * dy + dz * dz;
}

// Squared per-axis distances from the query to the current cell; their sum is a lower bound
// on the distance to any point in the cell (Arya & Mount's incremental distance).
struct Offsets {
  std::array<double, 3> squared;
  double Sum() const { return squared[0] + squared[1] + squared[2]; }
};

// The k closest so far, sorted by Closer, in the caller's out[0 .. count), and with
// kWithPoints their tree points in points_[0 .. count) (the caller's, k entries).
template <bool kWithPoints>
class KnnResult {
 public:
  // Only points within max_squared_distance (inclusive) are kept.
  KnnResult(int k, Neighbor* out, double max_squared_distance, const TreePoint** points = nullptr)
      : k_(k), out_(out), points_(points), max_squared_distance_(max_squared_distance) {}
  int count() const { return count_; }
  // Cells farther than this cannot improve the result.
  double bound() const {
    return count_ < k_ ? max_squared_distance_ : out_[k_ - 1].squared_distance_m2;
  }
  void Offer(double d, const TreePoint& p) {
    if (d > max_squared_distance_) return;
    internal::OfferNearest<const TreePoint*>(k_, d, p.index, &p, out_,
                                             kWithPoints ? points_ : nullptr, &count_);
  }

 private:
  int k_;
  Neighbor* out_;
  const TreePoint** points_;
  double max_squared_distance_;
  int count_ = 0;
};

// The closest point strictly inside the starting bound.
class NearestResult {
 public:
  explicit NearestResult(double max_squared_distance) : bound_(max_squared_distance) {}
  int index() const { return index_; }
  double bound() const { return bound_; }
  void Offer(double d, const TreePoint& p) {
    if (d < bound_ || (d == bound_ && index_ >= 0 && p.index < index_)) {
      bound_ = d;
      index_ = p.index;
    }
  }

 private:
  double bound_;
  int index_ = -1;
};

// Every point strictly inside the radius, unsorted.
class RadiusResult {
 public:
  RadiusResult(double squared_radius, std::vector<Neighbor>* out)
      : squared_radius_(squared_radius), out_(out) {}
  double bound() const { return squared_radius_; }
  void Offer(double d, const TreePoint& p) {
    if (d < squared_radius_) out_->push_back(Neighbor{p.index, d});
  }

 private:
  double squared_radius_;
  std::vector<Neighbor>* out_;
};

}  // namespace

struct KdTree::Impl {
  Impl(Eigen::Matrix3Xd p, int num_threads) : points(std::move(p)) {
    const int n = static_cast<int>(points.cols());
    if (n == 0) return;
    tree_points.resize(static_cast<size_t>(n));
    for (int i = 0; i < n; ++i) {
      tree_points[static_cast<size_t>(i)] =
          TreePoint{{points(0, i), points(1, i), points(2, i)}, i};
    }
    nodes.reserve(static_cast<size_t>(n) * 4 / kLeafMaxSize + 1);
    bounds = BoundsOf(tree_points.data(), tree_points.data() + n);
    int parallel_levels = 0;
    while ((1 << parallel_levels) < num_threads) ++parallel_levels;
    Build(0, n, bounds, parallel_levels, &nodes);
  }

  // How a cell splits: its points [begin, mid) go left, [mid, end) right.
  struct Split {
    int dim;
    int mid;
    Box left;
    Box right;
  };

  // Reorders the tree points [begin, end), which `box` bounds, into the two children of their
  // cell; none for a leaf.
  //
  // Split rule: cut the widest axis of the points' bounding box at its midpoint (cells stay
  // fat, which keeps the searched cells few in the very uneven density of a scan). A scan is
  // dense near the sensor, so the midpoint often leaves most points on one side; when one
  // side gets fewer than 1/kMinFraction of the points, cut instead at the median of
  // kSamples points spread over the range, and if even that is as lopsided (many equal
  // coordinates), at the exact median (std::nth_element). Either side then holds at least
  // 1/kMinFraction of the points, so the depth stays below log(n) / log(kMinFraction /
  // (kMinFraction - 1)).
  std::optional<Split> SplitOf(int begin, int end, const Box& box) {
    constexpr int kMinFraction = 8;
    constexpr int kSamples = 31;
    int dim = 0;
    for (int d = 1; d < 3; ++d) {
      if (box.max[d] - box.min[d] > box.max[dim] - box.min[dim]) dim = d;
    }
    const int count = end - begin;
    if (count <= kLeafMaxSize || box.max[dim] == box.min[dim]) return std::nullopt;
    TreePoint* const first = tree_points.data() + begin;
    TreePoint* const last = tree_points.data() + end;
    // The midpoint rounds into [min, max]; when it rounds to min, max is the next double and
    // "x < max" still splits both values apart.
    const double midpoint = 0.5 * (box.min[dim] + box.max[dim]);
    const double cut = midpoint > box.min[dim] ? midpoint : box.max[dim];
    const auto lopsided = [&](const TreePoint* split) {
      const int left_count = static_cast<int>(split - first);
      return std::min(left_count, count - left_count) * kMinFraction < count;
    };
    TreePoint* split = PartitionBelow(first, last, dim, cut);
    if (lopsided(split)) {
      std::array<double, kSamples> samples;
      for (int i = 0; i < kSamples; ++i) {
        const int64_t offset = static_cast<int64_t>(i) * count / kSamples;
        samples[static_cast<size_t>(i)] = first[offset].xyz[dim];
      }
      std::nth_element(samples.begin(), samples.begin() + kSamples / 2, samples.end());
      const double median = samples[kSamples / 2];
      split = PartitionBelow(first, last, dim, median > box.min[dim] ? median : box.max[dim]);
    }
    if (lopsided(split)) {
      split = first + count / 2;
      std::nth_element(first, split, last, [dim](const TreePoint& a, const TreePoint& b) {
        return a.xyz[dim] < b.xyz[dim];
      });
    }
    return Split{dim, static_cast<int>(split - tree_points.data()), BoundsOf(first, split),
                 BoundsOf(split, last)};
  }

  // Appends the subtree of tree points [begin, end), which `box` bounds, to *out in preorder
  // (a node, its left subtree, its right subtree) and returns its root's index in *out.
  // The top `parallel_levels` levels build their right subtree on another thread, into a
  // vector of its own appended afterwards: the same nodes as a build on one thread.
  int Build(int begin, int end, const Box& box, int parallel_levels, std::vector<Node>* out) {
    const int node = static_cast<int>(out->size());
    out->emplace_back();
    const std::optional<Split> split = SplitOf(begin, end, box);
    if (!split) {
      (*out)[static_cast<size_t>(node)].right_or_begin = begin;
      (*out)[static_cast<size_t>(node)].end = end;
      return node;
    }
    int right;
    if (parallel_levels > 0 && end - begin >= kMinParallelBuild) {
      std::vector<Node> right_nodes;
      right_nodes.reserve(static_cast<size_t>(end - split->mid) * 4 / kLeafMaxSize + 1);
      ParallelFor(0, 2, 2, [&](int64_t first, int64_t last, int) {
        for (int64_t side = first; side < last; ++side) {
          if (side == 0) {
            Build(begin, split->mid, split->left, parallel_levels - 1, out);
          } else {
            Build(split->mid, end, split->right, parallel_levels - 1, &right_nodes);
          }
        }
      });
      right = static_cast<int>(out->size());
      for (Node n : right_nodes) {
        if (n.dim >= 0) n.right_or_begin += right;  // a leaf's is a tree point index
        out->push_back(n);
      }
    } else {
      Build(begin, split->mid, split->left, 0, out);
      right = Build(split->mid, end, split->right, 0, out);
    }
    Node& n = (*out)[static_cast<size_t>(node)];
    n.dim = split->dim;
    n.left_max = split->left.max[split->dim];
    n.right_min = split->right.min[split->dim];
    n.right_or_begin = right;
    return node;
  }

  // Visits every cell whose lower bound does not exceed result->bound(), nearer child first.
  template <class Result>
  void Search(int node_index, const double* query, Offsets* offsets, Result* result) const {
    const Node& node = nodes[static_cast<size_t>(node_index)];
    if (node.dim < 0) {
      for (int i = node.right_or_begin; i < node.end; ++i) {
        const TreePoint& p = tree_points[static_cast<size_t>(i)];
        result->Offer(SquaredDistance(query, p.xyz), p);
      }
      return;
    }
    const int dim = node.dim;
    const double to_left = query[dim] - node.left_max;    // > 0: query right of the left cell
    const double to_right = node.right_min - query[dim];  // > 0: query left of the right cell
    const bool left_first = to_left < to_right;
    const int near_child = left_first ? node_index + 1 : node.right_or_begin;
    const int far_child = left_first ? node.right_or_begin : node_index + 1;
    const double far_gap = std::max(left_first ? to_right : to_left, 0.0);
    Search(near_child, query, offsets, result);
    const double saved = offsets->squared[dim];
    offsets->squared[dim] = far_gap * far_gap;
    if (offsets->Sum() <= result->bound()) Search(far_child, query, offsets, result);
    offsets->squared[dim] = saved;
  }

  template <class Result>
  void Search(const double* query, Result* result) const {
    Offsets offsets;
    for (int d = 0; d < 3; ++d) {
      const double gap = std::max({bounds.min[d] - query[d], query[d] - bounds.max[d], 0.0});
      offsets.squared[d] = gap * gap;
    }
    if (offsets.Sum() <= result->bound()) Search(0, query, &offsets, result);
  }

  Eigen::Matrix3Xd points;
  std::vector<TreePoint> tree_points;
  std::vector<Node> nodes;  // nodes[0] is the root
  Box bounds{};             // of all points
};

KdTree::KdTree(Eigen::Matrix3Xd points, int num_threads) {
  if (num_threads < 1) {
    throw Error("KdTree: num_threads must be at least 1, got " + std::to_string(num_threads));
  }
  if (!points.allFinite()) {
    for (Eigen::Index i = 0; i < points.cols(); ++i) {
      if (!points.col(i).allFinite()) {
        throw Error("KdTree: point " + std::to_string(i) + " has a non-finite coordinate");
      }
    }
  }
  if (points.cols() > std::numeric_limits<int>::max()) {
    throw Error("KdTree: too many points (" + std::to_string(points.cols()) + ")");
  }
  impl_ = std::make_unique<Impl>(std::move(points), num_threads);
}

KdTree::~KdTree() = default;
KdTree::KdTree(KdTree&&) noexcept = default;
KdTree& KdTree::operator=(KdTree&&) noexcept = default;

int64_t KdTree::size() const { return impl_->points.cols(); }

const Eigen::Matrix3Xd& KdTree::points() const { return impl_->points; }

bool KdTree::Nearest(const Eigen::Vector3d& query, double max_distance_m, Neighbor* nearest) const {
  if (size() == 0 || !(max_distance_m > 0.0)) return false;
  NearestResult result(max_distance_m * max_distance_m);
  impl_->Search(query.data(), &result);
  if (result.index() < 0) return false;
  nearest->index = result.index();
  nearest->squared_distance_m2 = result.bound();
  return true;
}

int KdTree::Knn(const Eigen::Vector3d& query, int k, Neighbor* out) const {
  return Knn(query, k, std::numeric_limits<double>::infinity(), out);
}

int KdTree::Knn(const Eigen::Vector3d& query, int k, double max_distance_m, Neighbor* out) const {
  if (k <= 0 || size() == 0 || !(max_distance_m >= 0.0)) return 0;
  KnnResult<false> result(k, out, max_distance_m * max_distance_m);
  impl_->Search(query.data(), &result);
  return result.count();
}

int KdTree::Knn(const Eigen::Vector3d& query, int k, double max_distance_m, Neighbor* out,
                double* points) const {
  if (k <= 0 || size() == 0 || !(max_distance_m >= 0.0)) return 0;
  // The tree's own copies of the points, which the search has just read: reading points()
  // by index instead would miss the cache.
  constexpr int kStackPoints = 32;
  std::array<const TreePoint*, kStackPoints> stack_found;
  std::vector<const TreePoint*> heap_found;
  const TreePoint** found = stack_found.data();
  if (k > kStackPoints) {
    heap_found.resize(static_cast<size_t>(k));
    found = heap_found.data();
  }
  KnnResult<true> result(k, out, max_distance_m * max_distance_m, found);
  impl_->Search(query.data(), &result);
  for (int i = 0; i < result.count(); ++i) {
    std::copy(found[i]->xyz.begin(), found[i]->xyz.end(), points + 3 * i);
  }
  return result.count();
}

std::vector<Neighbor> KdTree::Knn(const Eigen::Vector3d& query, int k) const {
  std::vector<Neighbor> out(static_cast<size_t>(std::max(k, 0)));
  out.resize(static_cast<size_t>(Knn(query, k, out.data())));
  return out;
}

void KdTree::RadiusSearch(const Eigen::Vector3d& query, double radius_m,
                          std::vector<Neighbor>* neighbors) const {
  neighbors->clear();
  if (size() == 0 || !(radius_m > 0.0)) return;
  RadiusResult result(radius_m * radius_m, neighbors);
  impl_->Search(query.data(), &result);
  // Sort by distance, then order runs of equal distance by index: the same order as sorting
  // by Closer, but the common comparison stays a single one.
  std::sort(neighbors->begin(), neighbors->end(), [](const Neighbor& a, const Neighbor& b) {
    return a.squared_distance_m2 < b.squared_distance_m2;
  });
  for (auto run = neighbors->begin(); run != neighbors->end();) {
    auto run_end = run + 1;
    while (run_end != neighbors->end() &&
           run_end->squared_distance_m2 == run->squared_distance_m2) {
      ++run_end;
    }
    if (run_end - run > 1) {
      std::sort(run, run_end,
                [](const Neighbor& a, const Neighbor& b) { return a.index < b.index; });
    }
    run = run_end;
  }
}

}  // namespace lidar
}  // namespace autocal
