#include "autocal/lidar/neighbor_grid.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "autocal/common/error.h"
#include "lidar/neighbor_search_clouds.h"

namespace autocal {
namespace lidar {
namespace {

// (squared distance, index) of every point within radius_m of the query, sorted: ties in
// distance by index, the order the grid promises. Summed x, y, z like the grid.
std::vector<std::pair<double, int>> BruteForce(const Eigen::Matrix3Xd& points,
                                               const Eigen::Vector3d& query, double radius_m) {
  std::vector<std::pair<double, int>> within;
  for (int i = 0; i < points.cols(); ++i) {
    const double dx = query.x() - points(0, i);
    const double dy = query.y() - points(1, i);
    const double dz = query.z() - points(2, i);
    const double d = dx * dx + dy * dy + dz * dz;
    if (d <= radius_m * radius_m) within.emplace_back(d, i);
  }
  std::sort(within.begin(), within.end());
  return within;
}

// Every query against brute force, for several k (also beyond the count within the radius and
// beyond the grid's stack buffer), with and without coordinates.
void ExpectMatchesBruteForce(const Eigen::Matrix3Xd& points, const Eigen::Matrix3Xd& queries,
                             double radius_m, const std::string& name) {
  const NeighborGrid grid(points, radius_m);
  ASSERT_EQ(grid.size(), points.cols());
  int nonempty = 0;
  for (int q = 0; q < queries.cols(); ++q) {
    SCOPED_TRACE(name + ", query " + std::to_string(q));
    const Eigen::Vector3d query = queries.col(q);
    const std::vector<std::pair<double, int>> brute = BruteForce(points, query, radius_m);
    nonempty += !brute.empty();
    for (const int k : {1, 3, 5, 16, 40}) {
      std::vector<Neighbor> found(static_cast<size_t>(k));
      Eigen::Matrix3Xd coordinates =
          Eigen::Matrix3Xd::Constant(3, k, std::numeric_limits<double>::quiet_NaN());
      const int count = grid.Knn(query, k, found.data(), coordinates.data());
      ASSERT_EQ(count, std::min<int>(k, static_cast<int>(brute.size()))) << "k " << k;
      std::vector<Neighbor> without(static_cast<size_t>(k));
      ASSERT_EQ(grid.Knn(query, k, without.data()), count) << "k " << k;
      for (int r = 0; r < count; ++r) {
        const size_t i = static_cast<size_t>(r);
        ASSERT_EQ(found[i].index, brute[i].second) << "k " << k << " rank " << r;
        ASSERT_EQ(found[i].squared_distance_m2, brute[i].first) << "k " << k << " rank " << r;
        ASSERT_EQ(without[i].index, found[i].index);
        ASSERT_TRUE((coordinates.col(r).array() == points.col(found[i].index).array()).all())
            << "k " << k << " rank " << r;
      }
    }
  }
  // The queries must exercise the search, not only its early exits.
  EXPECT_GT(nonempty, queries.cols() / 4) << name;
}

// Queries near random points of the cloud (within twice the radius), some exactly on points,
// and some around and beyond the cloud's bounds.
Eigen::Matrix3Xd QueriesFor(const Eigen::Matrix3Xd& points, double radius_m, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::Matrix3Xd queries(3, 120);
  for (int q = 0; q < queries.cols(); ++q) {
    const Eigen::Vector3d at = points.col(static_cast<Eigen::Index>(rng() % points.cols()));
    const Eigen::Vector3d jitter(u(rng), u(rng), u(rng));
    queries.col(q) = q % 4 == 0 ? at : Eigen::Vector3d(at + 2.0 * radius_m * jitter);
  }
  const Eigen::Vector3d low = points.rowwise().minCoeff(), high = points.rowwise().maxCoeff();
  for (int q = 0; q < 8; ++q) {  // just outside each corner of the bounds, and far outside
    const Eigen::Vector3d corner((q & 1) ? high.x() : low.x(), (q & 2) ? high.y() : low.y(),
                                 (q & 4) ? high.z() : low.z());
    const Eigen::Vector3d out((q & 1) ? 1.0 : -1.0, (q & 2) ? 1.0 : -1.0, (q & 4) ? 1.0 : -1.0);
    queries.col(q) = corner + 0.5 * radius_m * out;
    queries.col(8 + q) = corner + 5.0 * radius_m * out;
  }
  return queries;
}

TEST(NeighborGridTest, RandomCloudsMatchBruteForce) {
  const Eigen::Matrix3Xd flat = test::UniformPoints(3000, 5, Eigen::Vector3d(20.0, 20.0, 4.0));
  for (const double radius_m : {0.3, 1.0, 2.7}) {
    ExpectMatchesBruteForce(flat, QueriesFor(flat, radius_m, 6), radius_m,
                            "uniform, radius " + std::to_string(radius_m));
  }
  // Scan-like density: most points near the origin, a few far away; a tall column of points
  // (a pole) shares its grid column with everything below it.
  Eigen::Matrix3Xd scan = test::ScanLikePoints(4000, 7);
  for (int i = 0; i < 300; ++i) scan.col(i) = Eigen::Vector3d(2.0, -1.0, 0.05 * i);
  ExpectMatchesBruteForce(scan, QueriesFor(scan, 1.0, 8), 1.0, "scan-like");
}

TEST(NeighborGridTest, TiesAndBoundsMatchBruteForce) {
  const Eigen::Matrix3Xd duplicates = test::DuplicatedPoints();
  ExpectMatchesBruteForce(duplicates, QueriesFor(duplicates, 2.0, 12), 2.0, "duplicates");

  // A planar integer grid, with the radius an exact neighbour distance: queries at grid points
  // tie with 4 neighbours at exactly the radius, which counts.
  const Eigen::Matrix3Xd lattice = test::IntegerLattice();
  Eigen::Matrix3Xd queries = QueriesFor(lattice, 1.0, 15);
  for (int i = 0; i < 40; ++i) queries.col(16 + i) = Eigen::Vector3d(3 + i % 30, 17 - i % 5, 0.0);
  ExpectMatchesBruteForce(lattice, queries, 1.0, "lattice");
  std::vector<Neighbor> found(8);
  EXPECT_EQ(NeighborGrid(lattice, 1.0).Knn(Eigen::Vector3d(5.0, 5.0, 0.0), 8, found.data()), 5);
  // The same lattice at a radius that is no exact binary fraction, with points on the
  // boundaries of columns 0.1 m wide.
  ExpectMatchesBruteForce(0.1 * lattice, 0.1 * queries, 0.1, "lattice 0.1 m");
  // A neighbour at the radius whose column, by (x - origin) / radius rounded, would be two
  // away from the query's: 0.3 / 0.1 rounds to 3, 0.19999999999999998 / 0.1 to 1.99...
  Eigen::Matrix3Xd pair(3, 2);
  pair << 0.0, 0.3, 0.0, 0.0, 0.0, 0.0;
  const Eigen::Vector3d query(0.19999999999999998, 0.0, 0.0);
  ASSERT_EQ(BruteForce(pair, query, 0.1).size(), 1u);
  EXPECT_EQ(NeighborGrid(pair, 0.1).Knn(query, 2, found.data()), 1);
}

TEST(NeighborGridTest, CoarsensAGridTooLargeAndStaysExact) {
  // 1e4 km across at a 1 m radius: 1e14 columns, coarsened below the cap.
  Eigen::Matrix3Xd spread = test::UniformPoints(2000, 21, Eigen::Vector3d(2.0, 2.0, 2.0));
  spread.leftCols(1000) = test::UniformPoints(1000, 22, Eigen::Vector3d(5e6, 5e6, 1.0));
  const NeighborGrid grid(spread, 1.0);
  EXPECT_GT(grid.column_edge_m(), 1.0);
  const double columns = std::pow(std::ceil(1e7 / grid.column_edge_m()) + 1.0, 2.0);
  EXPECT_LE(columns, 1.1 * static_cast<double>(NeighborGrid::kMaxColumns));
  Eigen::Matrix3Xd queries = QueriesFor(spread.rightCols(1000), 1.0, 23);
  ExpectMatchesBruteForce(spread, queries, 1.0, "coarsened");
}

TEST(NeighborGridTest, EmptyAndOutOfReachQueriesFindNothing) {
  std::vector<Neighbor> found(5);
  const NeighborGrid empty(Eigen::Matrix3Xd(3, 0), 1.0);
  EXPECT_EQ(empty.size(), 0);
  EXPECT_EQ(empty.Knn(Eigen::Vector3d::Zero(), 5, found.data()), 0);

  const Eigen::Matrix3Xd points = test::UniformPoints(500, 31, Eigen::Vector3d(3.0, 3.0, 3.0));
  const NeighborGrid grid(points, 1.0);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  for (const Eigen::Vector3d& query :
       {Eigen::Vector3d(nan, 0.0, 0.0), Eigen::Vector3d(0.0, nan, 0.0),
        Eigen::Vector3d(0.0, 0.0, nan), Eigen::Vector3d(inf, 0.0, 0.0),
        Eigen::Vector3d(0.0, 0.0, -inf), Eigen::Vector3d(1e300, -1e300, 0.0),
        Eigen::Vector3d(0.0, 0.0, 50.0)}) {
    EXPECT_EQ(grid.Knn(query, 5, found.data()), 0) << query.transpose();
  }
  EXPECT_EQ(grid.Knn(Eigen::Vector3d::Zero(), 0, found.data()), 0);
  EXPECT_EQ(grid.Knn(Eigen::Vector3d::Zero(), 5, found.data()), 5);
}

TEST(NeighborGridTest, RejectsInvalidInput) {
  const Eigen::Matrix3Xd points = test::UniformPoints(10, 41, Eigen::Vector3d(1.0, 1.0, 1.0));
  for (const double radius_m : {0.0, -1.0, std::numeric_limits<double>::infinity(),
                                std::numeric_limits<double>::quiet_NaN()}) {
    EXPECT_THROW(NeighborGrid(points, radius_m), Error) << radius_m;
  }
  Eigen::Matrix3Xd bad = points;
  bad(2, 7) = std::numeric_limits<double>::quiet_NaN();
  try {
    NeighborGrid grid(bad, 1.0);
    FAIL() << "a non-finite point was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("point 7"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace lidar
}  // namespace autocal
