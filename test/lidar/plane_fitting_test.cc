#include "autocal/lidar/plane_fitting.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <random>

#include "autocal/common/error.h"
#include "autocal/common/units.h"
#include "lidar/synthetic_scene.h"

namespace autocal {
namespace lidar {
namespace {

// Points on a square patch of the plane through `centre` with unit normal `normal`, with
// isotropic Gaussian noise of sigma_m on every coordinate (a LiDAR's error is not only
// along z).
Eigen::Matrix3Xd NoisyPatch(const Eigen::Vector3d& centre, const Eigen::Vector3d& normal,
                            double half_size_m, int n, double sigma_m, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-half_size_m, half_size_m);
  std::normal_distribution<double> noise(0.0, sigma_m);
  const Eigen::Vector3d e1 = normal.unitOrthogonal();
  const Eigen::Vector3d e2 = normal.cross(e1);
  Eigen::Matrix3Xd points(3, n);
  for (int i = 0; i < n; ++i) {
    points.col(i) =
        centre + u(rng) * e1 + u(rng) * e2 + Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
  }
  return points;
}

double NormalAngleDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::min(1.0, std::abs(a.dot(b)))) * kRadToDeg;
}

TEST(PlaneFittingTest, HeightModelRecoversARoadWithinItsStatisticalError) {
  // A road surface z = a + b x + c y sampled like a LiDAR sees it, noise along z only (the
  // model's own assumption): the estimate must fall within 4 sigma of the truth, sigma
  // from the least-squares covariance sigma_z^2 (A^T A)^-1 (eq. 3.5).
  const HeightPlane truth{-1.8, 0.02, -0.015};
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<double> x(3.0, 40.0), y(-8.0, 8.0);
  std::normal_distribution<double> noise(0.0, 0.03);
  const int n = 3000;
  Eigen::Matrix3Xd points(3, n);
  Eigen::MatrixX3d A(n, 3);
  for (int i = 0; i < n; ++i) {
    points.col(i) = Eigen::Vector3d(x(rng), y(rng), 0.0);
    points(2, i) = truth.Height(points(0, i), points(1, i)) + noise(rng);
    A.row(i) << 1.0, points(0, i), points(1, i);
  }
  const HeightPlane fit = FitHeightPlane(points);
  const Eigen::Matrix3d covariance = 0.03 * 0.03 * (A.transpose() * A).inverse();
  const Eigen::Vector3d error(fit.a - truth.a, fit.b - truth.b, fit.c - truth.c);
  for (int k = 0; k < 3; ++k) {
    EXPECT_LT(std::abs(error(k)), 4.0 * std::sqrt(covariance(k, k)))
        << "coefficient " << k << " error " << error(k) << " sigma " << std::sqrt(covariance(k, k));
  }
  // The normal form describes the same plane.
  const geometry::Plane plane = fit.ToPlane();
  EXPECT_NEAR(plane.SignedDistance(Eigen::Vector3d(10.0, 2.0, fit.Height(10.0, 2.0))), 0.0, 1e-12);
  EXPECT_GT(plane.normal.z(), 0.0);
  // Total least squares agrees on this well-posed case.
  const PlaneFit tls = FitPlaneTotalLeastSquares(points);
  EXPECT_LT(NormalAngleDeg(tls.plane.normal, truth.ToPlane().normal), 0.05);
}

TEST(PlaneFittingTest, HeightModelFailsOnSteepPlanesWhereTotalLeastSquaresDoesNot) {
  // Tilting a plane towards vertical shrinks its x footprint until 1 cm of noise in x
  // rivals it. Regressing z on noisy x attenuates the slope by
  // lambda = var(x_true) / (var(x_true) + sigma^2) (errors in the regressors), so the fitted
  // tilt is atan(lambda tan(tilt)): the normal swings away from the truth, while the
  // orthogonal (TLS) fit is unaffected.
  const double sigma_m = 0.01;
  for (double tilt_deg : {10.0, 60.0, 89.0, 89.8}) {
    const double tilt = tilt_deg * kDegToRad;
    const Eigen::Vector3d normal(std::sin(tilt), 0.0, std::cos(tilt));
    const Eigen::Matrix3Xd points =
        NoisyPatch(Eigen::Vector3d(8.0, 1.0, 0.5), normal, 2.0, 2000, sigma_m, 17);
    const double tls_error_deg =
        NormalAngleDeg(FitPlaneTotalLeastSquares(points).plane.normal, normal);
    const double height_error_deg = NormalAngleDeg(FitHeightPlane(points).ToPlane().normal, normal);
    const Eigen::VectorXd x = points.row(0).transpose();
    const double var_x = (x.array() - x.mean()).square().mean();
    const double lambda = std::max(0.0, var_x - sigma_m * sigma_m) / var_x;
    const double predicted_error_deg = (tilt - std::atan(lambda * std::tan(tilt))) * kRadToDeg;
    SCOPED_TRACE("tilt " + std::to_string(tilt_deg) + " deg: height model error " +
                 std::to_string(height_error_deg) + " deg (attenuation predicts " +
                 std::to_string(predicted_error_deg) + "), TLS error " +
                 std::to_string(tls_error_deg) + " deg");
    EXPECT_LT(tls_error_deg, 0.1);
    if (tilt_deg < 80.0) {
      EXPECT_LT(height_error_deg, 0.1);
    } else {
      EXPECT_GT(height_error_deg, 5.0 * tls_error_deg);
      EXPECT_NEAR(height_error_deg, predicted_error_deg, 0.25 * predicted_error_deg);
    }
  }
  // Exactly vertical: the model cannot represent the plane at all.
  Eigen::Matrix3Xd wall(3, 40);
  for (int i = 0; i < 40; ++i) wall.col(i) = Eigen::Vector3d(5.0, 0.1 * i, 0.05 * (i % 7));
  EXPECT_THROW(FitHeightPlane(wall), Error);
  const PlaneFit fit = FitPlaneTotalLeastSquares(wall);
  EXPECT_NEAR(std::abs(fit.plane.normal.x()), 1.0, 1e-12);
  EXPECT_NEAR(std::abs(fit.plane.SignedDistance(Eigen::Vector3d(5.0, 3.0, 1.0))), 0.0, 1e-12);
}

TEST(PlaneFittingTest, DegenerateInputsGetClearErrors) {
  EXPECT_THROW(FitHeightPlane(Eigen::Matrix3Xd::Random(3, 2)), Error);
  EXPECT_THROW(FitPlaneTotalLeastSquares(Eigen::Matrix3Xd::Random(3, 2)), Error);
  Eigen::Matrix3Xd line(3, 10);
  for (int i = 0; i < 10; ++i) line.col(i) = Eigen::Vector3d(i, 2.0 * i, -i);
  EXPECT_THROW(FitPlaneTotalLeastSquares(line), Error);
  Eigen::Matrix3Xd bad = Eigen::Matrix3Xd::Random(3, 10);
  bad(0, 3) = std::nan("");
  EXPECT_THROW(FitHeightPlane(bad), Error);
  EXPECT_THROW(FitPlaneTotalLeastSquares(bad), Error);
  EXPECT_THROW(ExtractGround(bad), Error);
}

TEST(PlaneFittingTest, RansacExtractsTheGroundOfASimulatedStreet) {
  // A LiDAR 1.8 m above the road, pitched and rolled: the ground seen in the sensor frame
  // is the plane n_L . p + d = 0 with n_L = R_W_L^T z and d = 1.8 (the sensor height).
  const test::Scene scene = test::MakeStreetScene(12);
  const geometry::Pose3d T_W_L = test::MakePose(3.0, 0.5, 1.8, 15.0, 3.0, -2.0);
  test::ScanPattern pattern;
  pattern.range_noise_m = 0.02;
  std::mt19937_64 rng(13);
  const PointCloud scan = test::SimulateStaticSweep(scene, T_W_L, pattern, &rng);
  const GroundExtraction ground = ExtractGround(scan.points);

  const Eigen::Vector3d n_true = T_W_L.q.conjugate() * Eigen::Vector3d::UnitZ();
  EXPECT_LT(NormalAngleDeg(ground.plane.normal, n_true), 0.1)
      << ground.plane.normal.transpose() << " vs " << n_true.transpose();
  EXPECT_NEAR(ground.plane.d, T_W_L.p.z(), 0.01);
  EXPECT_GT(ground.plane.normal.dot(n_true), 0.0);

  // Inliers against the truth: ground points are those with world height ~0.
  int true_ground = 0, found_true = 0;
  std::vector<bool> is_inlier(static_cast<size_t>(scan.size()), false);
  for (int index : ground.inlier_indices) is_inlier[index] = true;
  for (int i = 0; i < scan.size(); ++i) {
    const double z_W = (T_W_L * Eigen::Vector3d(scan.points.col(i))).z();
    const bool on_ground = std::abs(z_W) < 0.1;  // 5 sigma of the range noise
    true_ground += on_ground;
    found_true += on_ground && is_inlier[i];
  }
  const double recall = static_cast<double>(found_true) / true_ground;
  const double precision = static_cast<double>(found_true) / ground.inlier_indices.size();
  EXPECT_GT(recall, 0.99) << found_true << " of " << true_ground;
  // Only box faces within 15 cm of the road surface may be taken for ground.
  EXPECT_GT(precision, 0.97) << found_true << " of " << ground.inlier_indices.size();
  EXPECT_LT(ground.iterations, 500);
}

TEST(PlaneFittingTest, RansacRejectsSceneWithoutGround) {
  Eigen::Matrix3Xd wall(3, 200);
  std::mt19937_64 rng(2);
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  for (int i = 0; i < 200; ++i) wall.col(i) = Eigen::Vector3d(6.0, u(rng), u(rng));
  EXPECT_THROW(ExtractGround(wall), Error);
}

}  // namespace
}  // namespace lidar
}  // namespace autocal
