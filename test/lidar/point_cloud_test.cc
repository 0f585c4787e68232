#include "autocal/lidar/point_cloud.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <string>
#include <tuple>

#include "autocal/common/error.h"
#include "autocal/common/units.h"
#include "autocal/lidar/kd_tree.h"
#include "autocal/lidar/normals.h"
#include "autocal/lidar/voxel_grid.h"
#include "lidar/synthetic_scene.h"

namespace autocal {
namespace lidar {
namespace {

PointCloud RandomCloud(int n, uint64_t seed, double extent_m = 50.0) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-extent_m, extent_m);
  PointCloud cloud;
  cloud.points.resize(3, n);
  cloud.intensity.resize(n);
  cloud.time_s.resize(n);
  for (int i = 0; i < n; ++i) {
    cloud.points.col(i) = Eigen::Vector3d(u(rng), u(rng), 0.2 * u(rng));
    cloud.intensity(i) = static_cast<float>(i % 256);
    cloud.time_s(i) = 1e-5 * i;
  }
  return cloud;
}

TEST(PointCloudTest, BatchOperationsMatchPerPointMath) {
  const PointCloud cloud = RandomCloud(500, 1);
  const geometry::Pose3d T_a_b = test::MakePose(3.0, -2.0, 0.5, 40.0, -5.0, 12.0);
  const Eigen::Vector3d s(2.0, 0.5, -1.0);
  const PointCloud translated = Translate(cloud, T_a_b.p);
  const PointCloud rotated = Rotate(cloud, T_a_b.R());
  const PointCloud scaled = Scale(cloud, s);
  const PointCloud scaled_iso = Scale(cloud, 3.0);
  const PointCloud transformed = Transform(cloud, T_a_b);
  PointCloud in_place = cloud;
  TransformInPlace(T_a_b, &in_place);
  for (int i = 0; i < cloud.size(); ++i) {
    const Eigen::Vector3d p = cloud.points.col(i);
    EXPECT_TRUE(translated.points.col(i).isApprox(p + T_a_b.p));
    EXPECT_TRUE(rotated.points.col(i).isApprox(T_a_b.q * p));
    EXPECT_TRUE(scaled.points.col(i).isApprox(s.cwiseProduct(p)));
    EXPECT_TRUE(scaled_iso.points.col(i).isApprox(3.0 * p));
    EXPECT_TRUE(transformed.points.col(i).isApprox(T_a_b * p, 1e-12));
    EXPECT_TRUE(in_place.points.col(i).isApprox(T_a_b * p, 1e-12));
  }
  // Channels travel with the points; transforming back restores the cloud.
  EXPECT_EQ(transformed.intensity, cloud.intensity);
  EXPECT_EQ(transformed.time_s, cloud.time_s);
  EXPECT_TRUE(Transform(transformed, T_a_b.Inverse()).points.isApprox(cloud.points, 1e-12));
}

TEST(PointCloudTest, RejectsNonRotationsAndBadChannels) {
  const PointCloud cloud = RandomCloud(10, 2);
  EXPECT_THROW(Rotate(cloud, Eigen::Vector3d(1, 1, -1).asDiagonal()), Error);  // reflection
  EXPECT_THROW(Rotate(cloud, 2.0 * Eigen::Matrix3d::Identity()), Error);
  PointCloud bad = cloud;
  bad.time_s.resize(3);
  EXPECT_THROW(CheckPointCloud(bad, "test"), Error);
  bad = cloud;
  bad.points(1, 4) = std::nan("");
  EXPECT_THROW(CheckPointCloud(bad, "test"), Error);
  const PointCloud cleaned = RemoveNonFinite(bad);
  EXPECT_EQ(cleaned.size(), cloud.size() - 1);
  EXPECT_EQ(cleaned.intensity(4), cloud.intensity(5));
  EXPECT_NO_THROW(CheckPointCloud(cleaned, "test"));
}

// A NaN or infinite time or intensity is refused like a coordinate, naming the point: the
// odometry deskews by time, and a NaN time made every later sweep fail in the local map.
TEST(PointCloudTest, RejectsNonFiniteTimeAndIntensityNamingThePoint) {
  const PointCloud cloud = RandomCloud(30, 6);
  const auto expect_refused = [](const PointCloud& bad, const std::string& message) {
    try {
      CheckPointCloud(bad, "sweep");
      ADD_FAILURE() << "expected: " << message;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(message), std::string::npos) << e.what();
    }
  };
  PointCloud bad = cloud;
  bad.time_s(17) = std::nan("");
  expect_refused(bad, "sweep: point 17 has a non-finite time (nan s)");
  bad.time_s(3) = -std::numeric_limits<double>::infinity();
  expect_refused(bad, "sweep: point 3 has a non-finite time (-inf s)");
  EXPECT_EQ(RemoveNonFinite(bad).size(), cloud.size() - 2);
  EXPECT_NO_THROW(CheckPointCloud(RemoveNonFinite(bad), "sweep"));
  bad = cloud;
  bad.intensity(29) = std::numeric_limits<float>::infinity();
  expect_refused(bad, "sweep: point 29 has a non-finite intensity (inf)");
  const PointCloud cleaned = RemoveNonFinite(bad);
  EXPECT_EQ(cleaned.size(), cloud.size() - 1);
  EXPECT_EQ(cleaned.time_s(28), cloud.time_s(28));
  EXPECT_NO_THROW(CheckPointCloud(cleaned, "sweep"));
  // A non-finite coordinate is named first.
  bad.points(0, 5) = std::nan("");
  expect_refused(bad, "sweep: point 5 has a non-finite coordinate");
}

TEST(VoxelGridTest, CentroidPerOccupiedVoxel) {
  const PointCloud cloud = RandomCloud(20000, 3, 10.0);
  const double voxel_m = 0.7;
  const PointCloud down = VoxelDownsample(cloud, voxel_m);
  // Reference: a map keyed by the voxel index relative to the cloud's minimum corner.
  const Eigen::Vector3d min_corner = cloud.points.rowwise().minCoeff();
  std::map<std::tuple<int64_t, int64_t, int64_t>, std::pair<Eigen::Vector3d, int>> voxels;
  for (int i = 0; i < cloud.size(); ++i) {
    const Eigen::Vector3d v = (cloud.points.col(i) - min_corner) / voxel_m;
    auto& entry = voxels[{static_cast<int64_t>(v.x()), static_cast<int64_t>(v.y()),
                          static_cast<int64_t>(v.z())}];
    if (entry.second == 0) entry.first.setZero();
    entry.first += cloud.points.col(i);
    ++entry.second;
  }
  ASSERT_EQ(static_cast<size_t>(down.size()), voxels.size());
  ASSERT_TRUE(down.has_intensity());
  ASSERT_TRUE(down.has_time());
  int i = 0;
  for (const auto& [key, entry] : voxels) {  // both ordered by (x, y, z) index
    const Eigen::Vector3d centroid = entry.first / entry.second;
    EXPECT_TRUE(down.points.col(i).isApprox(centroid, 1e-12))
        << "voxel " << i << ": " << down.points.col(i).transpose() << " vs "
        << centroid.transpose();
    ++i;
  }
}

// The input order changes which voxels there are and their order not at all, and their means
// by rounding only, within the documented bound: about 2n * 2^-53 times the largest
// magnitude summed, for a voxel of n points (nothing for n <= 2).
TEST(VoxelGridTest, InputOrderChangesTheMeansByRoundingOnly) {
  // About 12 points per voxel, so that sums in another order round differently.
  const PointCloud dense = RandomCloud(20000, 4, 10.0);
  const double voxel_m = 1.0;
  const PointCloud a = VoxelDownsample(dense, voxel_m);
  // Per voxel, in the output's (x, y, z) index order: its count and largest magnitudes.
  struct Summed {
    int count = 0;
    Eigen::Vector3d max_abs_m = Eigen::Vector3d::Zero();
    double max_abs_time_s = 0.0;
  };
  const Eigen::Vector3d min_corner = dense.points.rowwise().minCoeff();
  std::map<std::tuple<int64_t, int64_t, int64_t>, Summed> voxels;
  for (int64_t i = 0; i < dense.size(); ++i) {
    const Eigen::Vector3d v = (dense.points.col(i) - min_corner) / voxel_m;
    Summed& voxel = voxels[{static_cast<int64_t>(v.x()), static_cast<int64_t>(v.y()),
                            static_cast<int64_t>(v.z())}];
    ++voxel.count;
    voxel.max_abs_m = voxel.max_abs_m.cwiseMax(dense.points.col(i).cwiseAbs());
    voxel.max_abs_time_s = std::max(voxel.max_abs_time_s, std::abs(dense.time_s(i)));
  }
  ASSERT_EQ(static_cast<size_t>(a.size()), voxels.size());

  PointCloud reversed = dense;
  reversed.points = dense.points.rowwise().reverse();
  reversed.intensity = dense.intensity.reverse();
  reversed.time_s = dense.time_s.reverse();
  std::vector<int> permutation(static_cast<size_t>(dense.size()));
  for (size_t i = 0; i < permutation.size(); ++i) permutation[i] = static_cast<int>(i);
  std::shuffle(permutation.begin(), permutation.end(), std::mt19937_64(5));
  PointCloud shuffled = dense;
  for (int64_t i = 0; i < dense.size(); ++i) {
    const int from = permutation[static_cast<size_t>(i)];
    shuffled.points.col(i) = dense.points.col(from);
    shuffled.intensity(i) = dense.intensity(from);
    shuffled.time_s(i) = dense.time_s(from);
  }
  constexpr double kUnitRoundoff = 0x1p-53;
  for (const PointCloud* reordered : {&reversed, &shuffled}) {
    const PointCloud b = VoxelDownsample(*reordered, voxel_m);
    ASSERT_EQ(b.size(), a.size());
    int changed = 0;
    int64_t k = 0;
    for (const auto& [index, voxel] : voxels) {
      const double factor = 2.0 * voxel.count * kUnitRoundoff;
      for (int axis = 0; axis < 3; ++axis) {
        const double difference = std::abs(b.points(axis, k) - a.points(axis, k));
        if (voxel.count <= 2) {
          EXPECT_EQ(difference, 0.0) << "voxel " << k;
        }
        EXPECT_LE(difference, factor * voxel.max_abs_m(axis)) << "voxel " << k << " axis " << axis;
      }
      EXPECT_LE(std::abs(b.time_s(k) - a.time_s(k)), factor * voxel.max_abs_time_s) << k;
      // The intensities are integers: their sums are exact in any order.
      EXPECT_EQ(b.intensity(k), a.intensity(k)) << "voxel " << k;
      changed += b.points.col(k) != a.points.col(k);
      ++k;
    }
    // The data do exercise the bound: some sums round differently in another order.
    EXPECT_GT(changed, 0);
    RecordProperty(
        reordered == &reversed ? "centroids_changed_reversed" : "centroids_changed_shuffled",
        std::to_string(changed) + " of " + std::to_string(a.size()));
  }
}

TEST(VoxelGridTest, RejectsBadInput) {
  PointCloud cloud = RandomCloud(5000, 4);
  EXPECT_THROW(VoxelDownsample(cloud, 0.0), Error);
  EXPECT_THROW(VoxelDownsample(cloud, -1.0), Error);
  EXPECT_THROW(VoxelDownsample(cloud, 1e-6), Error);  // 2^21 voxels per axis exceeded
  cloud.points(2, 10) = std::numeric_limits<double>::infinity();
  EXPECT_THROW(VoxelDownsample(cloud, 1.0), Error);
  EXPECT_EQ(VoxelDownsample(PointCloud(), 1.0).size(), 0);
}

TEST(NormalsTest, SimulatedScanNormalsMatchTheSurfaces) {
  // Ray-cast scene: every point lies on the ground (normal z) or on a box face (normal x
  // or y); far from edges the PCA normal must be the face normal, facing the sensor.
  const test::Scene scene = test::MakeStreetScene(8);
  std::mt19937_64 rng(9);
  const geometry::Pose3d T_W_L = test::MakePose(0.0, 0.0, 1.8, 0.0, 0.0, 0.0);
  const PointCloud scan = VoxelDownsample(test::SimulateStaticSweep(scene, T_W_L, {}, &rng), 0.2);
  const KdTree tree(scan.points);
  NormalEstimationOptions setting;
  setting.max_radius_m = 1.0;
  const SurfaceNormals normals = EstimateNormals(tree, setting);
  int checked = 0;
  for (int i = 0; i < scan.size(); ++i) {
    const Eigen::Vector3d p_W = T_W_L * Eigen::Vector3d(scan.points.col(i));
    if (normals.planarity(i) < 0.5) continue;
    // The true surface: the ground if the point is on it, else the nearest box face.
    Eigen::Vector3d truth = Eigen::Vector3d::UnitZ();
    if (std::abs(p_W.z()) > 0.05) {
      double best = 1e9;
      for (const test::Box& box : scene.boxes) {
        for (int axis = 0; axis < 2; ++axis) {
          for (double face : {box.min_corner(axis), box.max_corner(axis)}) {
            const Eigen::Vector3d clamped = p_W.cwiseMax(box.min_corner).cwiseMin(box.max_corner);
            const double d = std::abs(p_W(axis) - face) + (clamped - p_W).norm();
            if (d < best) {
              best = d;
              truth = Eigen::Vector3d::Unit(axis);
            }
          }
        }
      }
      if (best > 0.05) continue;
    }
    // Skip points near an edge, where the neighbourhood straddles two faces.
    std::vector<Neighbor> near;
    tree.RadiusSearch(scan.points.col(i), setting.max_radius_m, &near);
    bool near_edge = false;
    for (const Neighbor& nb : near) {
      const Eigen::Vector3d q_W = T_W_L * Eigen::Vector3d(scan.points.col(nb.index));
      near_edge |= std::abs((q_W - p_W).dot(truth)) > 0.05;
    }
    if (near_edge) continue;
    const Eigen::Vector3d n_W = T_W_L.q * Eigen::Vector3d(normals.normals.col(i));
    EXPECT_GT(std::abs(n_W.dot(truth)), std::cos(1.0 * kDegToRad))
        << "point " << p_W.transpose() << " normal " << n_W.transpose() << " truth "
        << truth.transpose();
    // Oriented towards the sensor.
    EXPECT_GE(n_W.dot(T_W_L.p - p_W), 0.0);
    ++checked;
  }
  EXPECT_GT(checked, scan.size() / 3);
}

TEST(NormalsTest, PlanarityTellsPlanesFromLines) {
  std::mt19937_64 rng(10);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  // A square grid patch (isotropic in its plane, so l1 = l2) and a thin line.
  Eigen::Matrix3Xd plane(3, 49), line(3, 49);
  for (int i = 0; i < 49; ++i) {
    plane.col(i) = Eigen::Vector3d(i % 7 - 3.0, i / 7 - 3.0, 0.001 * u(rng));
    line.col(i) = Eigen::Vector3d(u(rng), 0.001 * u(rng), 0.001 * u(rng));
  }
  Eigen::Vector3d normal;
  double planarity = 0.0;
  ASSERT_TRUE(PcaNormal(plane, &normal, &planarity));
  EXPECT_GT(std::abs(normal.z()), 0.9999);
  EXPECT_GT(planarity, 0.95);
  ASSERT_TRUE(PcaNormal(line, &normal, &planarity));
  EXPECT_LT(planarity, 0.01);
  EXPECT_FALSE(PcaNormal(plane.leftCols(2), &normal, &planarity));
  EXPECT_FALSE(PcaNormal(Eigen::Matrix3Xd::Ones(3, 5), &normal, &planarity));
}

}  // namespace
}  // namespace lidar
}  // namespace autocal
