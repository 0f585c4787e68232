#include "autocal/lidar/kd_tree.h"

#include <algorithm>
#include <limits>
#include <nanoflann.hpp>
#include <string>

#include "autocal/common/error.h"

namespace autocal {
namespace lidar {
namespace {

// nanoflann's dataset interface over the columns of a 3xN matrix.
struct MatrixAdaptor {
  const Eigen::Matrix3Xd* points = nullptr;

  size_t kdtree_get_point_count() const { return static_cast<size_t>(points->cols()); }
  double kdtree_get_pt(size_t index, size_t dim) const {
    return (*points)(static_cast<Eigen::Index>(dim), static_cast<Eigen::Index>(index));
  }
  template <class BoundingBox>
  bool kdtree_get_bbox(BoundingBox& /*bbox*/) const {
    return false;
  }
};

using Index =
    nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, MatrixAdaptor>,
                                        MatrixAdaptor, 3, uint32_t>;

// The nearest neighbour inside a bound: nanoflann only descends into cells closer than
// worstDist(), so starting from the bound instead of infinity skips most of the tree for
// queries without a close match (nanoflann 1.4 result-set interface).
class NearestWithin {
 public:
  explicit NearestWithin(double max_squared_distance) : worst_(max_squared_distance) {}
  bool full() const { return true; }
  double worstDist() const { return worst_; }
  bool addPoint(double squared_distance, uint32_t index) {
    if (squared_distance < worst_) {
      worst_ = squared_distance;
      index_ = static_cast<int>(index);
    }
    return true;
  }
  int index() const { return index_; }

 private:
  double worst_;
  int index_ = -1;
};

// Collects every point inside the radius straight into the caller's vector.
class WithinRadius {
 public:
  WithinRadius(double squared_radius, std::vector<Neighbor>* out)
      : squared_radius_(squared_radius), out_(out) {}
  bool full() const { return true; }
  double worstDist() const { return squared_radius_; }
  bool addPoint(double squared_distance, uint32_t index) {
    if (squared_distance < squared_radius_) {
      out_->push_back(Neighbor{static_cast<int>(index), squared_distance});
    }
    return true;
  }

 private:
  double squared_radius_;
  std::vector<Neighbor>* out_;
};

constexpr size_t kLeafMaxSize = 16;

}  // namespace

struct KdTree::Impl {
  explicit Impl(Eigen::Matrix3Xd p)
      : points(std::move(p)),
        adaptor{&points},
        index(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(kLeafMaxSize)) {}

  Eigen::Matrix3Xd points;
  MatrixAdaptor adaptor;
  Index index;
};

KdTree::KdTree(Eigen::Matrix3Xd points) {
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
  impl_ = std::make_unique<Impl>(std::move(points));
}

KdTree::~KdTree() = default;
KdTree::KdTree(KdTree&&) noexcept = default;
KdTree& KdTree::operator=(KdTree&&) noexcept = default;

int64_t KdTree::size() const { return impl_->points.cols(); }

const Eigen::Matrix3Xd& KdTree::points() const { return impl_->points; }

bool KdTree::Nearest(const Eigen::Vector3d& query, double max_distance_m, Neighbor* nearest) const {
  if (size() == 0 || !(max_distance_m > 0.0)) return false;
  NearestWithin result(max_distance_m * max_distance_m);
  impl_->index.findNeighbors(result, query.data(), nanoflann::SearchParams());
  if (result.index() < 0) return false;
  nearest->index = result.index();
  nearest->squared_distance_m2 = result.worstDist();
  return true;
}

int KdTree::Knn(const Eigen::Vector3d& query, int k, Neighbor* out) const {
  if (k <= 0 || size() == 0) return 0;
  constexpr int kStackCapacity = 64;
  uint32_t stack_indices[kStackCapacity];
  double stack_distances[kStackCapacity];
  std::vector<uint32_t> heap_indices;
  std::vector<double> heap_distances;
  uint32_t* indices = stack_indices;
  double* distances = stack_distances;
  if (k > kStackCapacity) {
    heap_indices.resize(static_cast<size_t>(k));
    heap_distances.resize(static_cast<size_t>(k));
    indices = heap_indices.data();
    distances = heap_distances.data();
  }
  nanoflann::KNNResultSet<double, uint32_t, size_t> result(static_cast<size_t>(k));
  result.init(indices, distances);
  impl_->index.findNeighbors(result, query.data(), nanoflann::SearchParams());
  const int found = static_cast<int>(result.size());
  for (int i = 0; i < found; ++i) out[i] = Neighbor{static_cast<int>(indices[i]), distances[i]};
  return found;
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
  WithinRadius result(radius_m * radius_m, neighbors);
  impl_->index.findNeighbors(result, query.data(), nanoflann::SearchParams());
  std::sort(neighbors->begin(), neighbors->end(), [](const Neighbor& a, const Neighbor& b) {
    return a.squared_distance_m2 < b.squared_distance_m2;
  });
}

}  // namespace lidar
}  // namespace autocal
