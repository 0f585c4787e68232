#include "autocal/lidar/kd_tree.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/io/point_cloud_file.h"
#include "lidar/neighbor_search_clouds.h"
#include "support/test_paths.h"

namespace autocal {
namespace lidar {
namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();

// (squared distance, index) of every point, sorted: ties in distance by index, the order the
// tree promises. The distance is summed x, y, z like the tree's.
std::vector<std::pair<double, int>> BruteForce(const Eigen::Matrix3Xd& points,
                                               const Eigen::Vector3d& query) {
  std::vector<std::pair<double, int>> all;
  for (int i = 0; i < points.cols(); ++i) {
    const double dx = query.x() - points(0, i);
    const double dy = query.y() - points(1, i);
    const double dz = query.z() - points(2, i);
    all.emplace_back(dx * dx + dy * dy + dz * dz, i);
  }
  std::sort(all.begin(), all.end());
  return all;
}

// Checks every query type against brute force: Knn for several k,
// Nearest without bound and with bounds around the nearest and a farther distance, and
// RadiusSearch for radii around a few neighbour distances.
void ExpectMatchesBruteForce(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& queries,
                             const std::string& name, int num_threads = 1) {
  const KdTree tree(points, num_threads);
  ASSERT_EQ(tree.size(), points.cols());
  const int n = static_cast<int>(points.cols());
  std::vector<Neighbor> radius_result;
  for (int q = 0; q < queries.cols(); ++q) {
    SCOPED_TRACE(name + ", query " + std::to_string(q));
    const Eigen::Vector3d query = queries.col(q);
    const std::vector<std::pair<double, int>> brute = BruteForce(points, query);

    // k beyond size() on small clouds; a long list on large ones (the insertion is O(k²)).
    for (const int k : {1, 5, 16, 40, n <= 4000 ? n + 3 : 300}) {
      const std::vector<Neighbor> knn = tree.Knn(query, k);
      ASSERT_EQ(static_cast<int>(knn.size()), std::min(k, n)) << "k " << k;
      for (size_t r = 0; r < knn.size(); ++r) {
        ASSERT_EQ(knn[r].index, brute[r].second) << "k " << k << " rank " << r;
        ASSERT_EQ(knn[r].squared_distance_m2, brute[r].first) << "k " << k << " rank " << r;
      }
    }

    // Bounded k-NN: the k nearest among the points no farther than the bound (inclusive: a
    // bound exactly at a neighbour's distance keeps it).
    Neighbor bounded[16];
    for (const size_t rank : {size_t{0}, size_t{3}, size_t{12}}) {
      if (n == 0) break;
      const double at_m = std::sqrt(brute[std::min(rank, brute.size() - 1)].first);
      for (const double bound_m : {at_m, 0.999 * at_m, 1.001 * at_m + 1e-9}) {
        const int expected = static_cast<int>(std::min<size_t>(
            16, static_cast<size_t>(std::count_if(brute.begin(), brute.end(), [&](const auto& e) {
              return e.first <= bound_m * bound_m;
            }))));
        ASSERT_EQ(tree.Knn(query, 16, bound_m, bounded), expected) << "bound " << bound_m;
        for (int r = 0; r < expected; ++r) {
          ASSERT_EQ(bounded[r].index, brute[static_cast<size_t>(r)].second) << "bound " << bound_m;
          ASSERT_EQ(bounded[r].squared_distance_m2, brute[static_cast<size_t>(r)].first);
        }
      }
    }
    // With the coordinates: the same neighbours, each with its point's exact coordinates; also
    // for more neighbours than the search keeps on its stack.
    for (const int k : {5, 40}) {
      if (n == 0) break;
      const double bound_m = std::sqrt(brute[std::min<size_t>(20, brute.size() - 1)].first);
      std::vector<Neighbor> plain(static_cast<size_t>(k)), with_points(static_cast<size_t>(k));
      Eigen::Matrix3Xd coordinates = Eigen::Matrix3Xd::Constant(3, k, kInfinity);
      const int count = tree.Knn(query, k, bound_m, plain.data());
      ASSERT_EQ(tree.Knn(query, k, bound_m, with_points.data(), coordinates.data()), count);
      for (int r = 0; r < count; ++r) {
        const size_t i = static_cast<size_t>(r);
        ASSERT_EQ(with_points[i].index, plain[i].index) << "k " << k << " rank " << r;
        ASSERT_EQ(with_points[i].squared_distance_m2, plain[i].squared_distance_m2);
        ASSERT_TRUE((coordinates.col(r).array() == points.col(plain[i].index).array()).all())
            << "k " << k << " rank " << r;
      }
    }

    Neighbor nearest;
    if (n == 0) {
      EXPECT_FALSE(tree.Nearest(query, kInfinity, &nearest));
      continue;
    }
    ASSERT_TRUE(tree.Nearest(query, kInfinity, &nearest));
    EXPECT_EQ(nearest.index, brute[0].second);
    EXPECT_EQ(nearest.squared_distance_m2, brute[0].first);
    // Bounds just below and above the nearest distance, and at farther neighbours' distances.
    // Only points strictly closer than the bound count.
    const double nearest_m = std::sqrt(brute[0].first);
    for (const double bound_m :
         {0.999 * nearest_m, 1.001 * nearest_m + 1e-9, std::sqrt(brute[std::min(3, n - 1)].first),
          std::sqrt(brute[static_cast<size_t>(n - 1)].first) + 1.0}) {
      const bool expected = brute[0].first < bound_m * bound_m;
      ASSERT_EQ(tree.Nearest(query, bound_m, &nearest), expected) << "bound " << bound_m;
      if (expected) {
        EXPECT_EQ(nearest.index, brute[0].second);
        EXPECT_EQ(nearest.squared_distance_m2, brute[0].first);
      }
    }

    for (const size_t rank : {size_t{0}, size_t{4}, size_t{30}, brute.size() - 1}) {
      const double radius_m = std::sqrt(brute[std::min(rank, brute.size() - 1)].first) + 1e-3;
      tree.RadiusSearch(query, radius_m, &radius_result);
      const size_t expected =
          static_cast<size_t>(std::count_if(brute.begin(), brute.end(), [&](const auto& e) {
            return e.first < radius_m * radius_m;
          }));
      ASSERT_EQ(radius_result.size(), expected) << "radius " << radius_m;
      for (size_t r = 0; r < expected; ++r) {
        ASSERT_EQ(radius_result[r].index, brute[r].second) << "radius " << radius_m;
        ASSERT_EQ(radius_result[r].squared_distance_m2, brute[r].first);
      }
    }
  }
}

// Queries in and around the cloud, plus some of its own points (distance 0, and ties when
// the cloud has duplicates).
Eigen::Matrix3Xd QueriesFor(const Eigen::Matrix3Xd& points, uint64_t seed) {
  constexpr int kRandom = 60;
  constexpr int kOwn = 20;
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  Eigen::Vector3d half_extent = Eigen::Vector3d::Ones();
  if (points.cols() > 0) {
    center = 0.5 * (points.rowwise().minCoeff() + points.rowwise().maxCoeff());
    half_extent = (0.5 * (points.rowwise().maxCoeff() - points.rowwise().minCoeff())).cwiseMax(1.0);
  }
  Eigen::Matrix3Xd queries = test::UniformPoints(kRandom + kOwn, seed, 1.3 * half_extent);
  queries.colwise() += center;
  std::mt19937_64 rng(seed + 1);
  for (int i = 0; i < kOwn && points.cols() > 0; ++i) {
    queries.col(kRandom + i) = points.col(static_cast<Eigen::Index>(rng() % points.cols()));
  }
  return queries;
}

TEST(KdTreeTest, RandomCloudsMatchBruteForce) {
  const Eigen::Matrix3Xd flat = test::UniformPoints(3000, 5, Eigen::Vector3d(20.0, 20.0, 4.0));
  ExpectMatchesBruteForce(flat, QueriesFor(flat, 6), "uniform");
  // Scan-like density: most points near the origin, a few far away (uneven cells).
  const Eigen::Matrix3Xd scan = test::ScanLikePoints(4000, 7);
  ExpectMatchesBruteForce(scan, QueriesFor(scan, 8), "scan-like");
}

// Large enough that the top two levels are built on their own threads, whose subtrees are
// spliced into the node list: a wrong offset sends the search into the wrong cells.
TEST(KdTreeTest, TreeBuiltOnSeveralThreadsMatchesBruteForce) {
  const Eigen::Matrix3Xd scan = test::ScanLikePoints(40000, 21);
  for (const int num_threads : {2, 3, 4}) {
    ExpectMatchesBruteForce(scan, QueriesFor(scan, 22), "scan-like", num_threads);
  }
  const Eigen::Matrix3Xd uniform = test::UniformPoints(30000, 23, Eigen::Vector3d(50.0, 50.0, 5.0));
  ExpectMatchesBruteForce(uniform, QueriesFor(uniform, 24), "uniform", 2);
  EXPECT_THROW(KdTree(uniform, 0), Error);
}

TEST(KdTreeTest, DegenerateCloudsMatchBruteForce) {
  const Eigen::Matrix3Xd duplicates = test::DuplicatedPoints();
  ExpectMatchesBruteForce(duplicates, QueriesFor(duplicates, 12), "duplicates");

  const Eigen::Matrix3Xd all_equal = Eigen::Vector3d(1.0, -2.0, 3.0).replicate(1, 300);
  ExpectMatchesBruteForce(all_equal, QueriesFor(all_equal, 13), "all equal");

  // Collinear points on a diagonal line, with an integer spacing that makes equal distances.
  Eigen::Matrix3Xd line(3, 500);
  for (int i = 0; i < line.cols(); ++i) line.col(i) = (i % 250) * Eigen::Vector3d(1.0, 2.0, -1.0);
  ExpectMatchesBruteForce(line, QueriesFor(line, 14), "collinear");

  // A planar integer grid: queries at grid points tie with up to 4 or 8 neighbours.
  const Eigen::Matrix3Xd grid = test::IntegerLattice();
  Eigen::Matrix3Xd grid_queries = QueriesFor(grid, 15);
  for (int i = 0; i < 20; ++i) grid_queries.col(i) = Eigen::Vector3d(3 + i, 17 - i % 5, 0.0);
  ExpectMatchesBruteForce(grid, grid_queries, "planar grid");

  ExpectMatchesBruteForce(Eigen::Matrix3Xd(Eigen::Vector3d(4.0, 5.0, 6.0)),
                          QueriesFor(Eigen::Vector3d(4.0, 5.0, 6.0), 16), "one point");
  ExpectMatchesBruteForce(Eigen::Matrix3Xd(3, 0), QueriesFor(Eigen::Matrix3Xd(3, 0), 17),
                          "no points");
}

TEST(KdTreeTest, RealScanMatchesBruteForce) {
  const std::filesystem::path dir = test::SharedDataDir("lidar_scan_pair");
  AUTOCAL_REQUIRE_SHARED_DATA(dir);
  const Eigen::Matrix3Xd source = io::ReadPointCloudFile((dir / "source.ply").string()).points;
  const Eigen::Matrix3Xd target = io::ReadPointCloudFile((dir / "target.ply").string()).points;
  Eigen::Matrix3Xd queries(3, 40);
  for (int i = 0; i < queries.cols(); ++i) {
    queries.col(i) = target.col(static_cast<Eigen::Index>(i) * target.cols() / queries.cols());
  }
  ExpectMatchesBruteForce(source, queries, "real scan");
}

TEST(KdTreeTest, EdgeCasesAndErrors) {
  EXPECT_THROW(KdTree(Eigen::Matrix3Xd::Constant(3, 4, std::nan(""))), Error);
  Eigen::Matrix3Xd points = test::UniformPoints(100, 21, Eigen::Vector3d::Ones());
  points(1, 57) = kInfinity;
  EXPECT_THROW(KdTree{points}, Error);
  points(1, 57) = 0.0;

  KdTree moved_from(points);
  const KdTree tree(std::move(moved_from));
  const Eigen::Vector3d query(0.1, 0.2, 0.3);
  Neighbor nearest;
  EXPECT_FALSE(tree.Nearest(query, 0.0, &nearest));
  EXPECT_FALSE(tree.Nearest(query, -1.0, &nearest));
  EXPECT_TRUE(tree.Knn(query, 0).empty());
  EXPECT_TRUE(tree.Knn(query, -2).empty());
  std::vector<Neighbor> neighbors{Neighbor{3, 1.0}};
  tree.RadiusSearch(query, 0.0, &neighbors);
  EXPECT_TRUE(neighbors.empty());
  // Indices refer to the points in their given order.
  ASSERT_TRUE(tree.Nearest(points.col(42), kInfinity, &nearest));
  EXPECT_EQ(nearest.index, 42);
  EXPECT_EQ(nearest.squared_distance_m2, 0.0);
  EXPECT_TRUE((tree.points().array() == points.array()).all());
}

}  // namespace
}  // namespace lidar
}  // namespace autocal
