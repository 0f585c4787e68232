#include "autocal/lidar/registration.h"

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <random>
#include <sstream>
#include <string>

#include "autocal/common/error.h"
#include "lidar/synthetic_scene.h"

namespace autocal {
namespace lidar {
namespace {

using geometry::Pose3d;

TEST(RegistrationTest, SettingValidatesEveryOption) {
  const RegistrationOptions setting =
      MakeRegistrationOptions("point_to_point", "huber", 0.2, 0.5, 2.0);
  EXPECT_EQ(setting.icp.method, IcpMethod::kPointToPoint);
  EXPECT_EQ(setting.icp.robust.loss, factors::RobustLoss::kHuber);
  EXPECT_EQ(setting.icp.robust.scale_m, 0.2);
  EXPECT_EQ(setting.voxel_m, 0.5);
  EXPECT_EQ(setting.icp.max_correspondence_m, 2.0);
  EXPECT_THROW(MakeRegistrationOptions("plane", "none", 0.1, 0.25, 1.0), Error);
  EXPECT_THROW(MakeRegistrationOptions("point_to_plane", "l1", 0.1, 0.25, 1.0), Error);
  EXPECT_THROW(MakeRegistrationOptions("point_to_plane", "none", 0.0, 0.25, 1.0), Error);
  EXPECT_THROW(MakeRegistrationOptions("point_to_plane", "none", 0.1, -1.0, 1.0), Error);
  EXPECT_THROW(MakeRegistrationOptions("point_to_plane", "none", 0.1, 0.25, 0.0), Error);
  EXPECT_THROW(MakeRegistrationOptions("point_to_plane", "none", 0.1, std::nan(""), 1.0), Error);
}

// --init: six numbers (m, deg) or a 4x4 matrix in any of the usual spellings.
TEST(RegistrationTest, PoseGuessFromSixNumbersOrAMatrix) {
  const Pose3d six = ParsePoseGuess("1, 2, 3, 90, 0, -90", "--init");
  EXPECT_LT((six.p - Eigen::Vector3d(1, 2, 3)).norm(), 1e-15);
  const Eigen::Quaterniond expected(Eigen::AngleAxisd(-M_PI / 2, Eigen::Vector3d::UnitZ()) *
                                    Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitX()));
  EXPECT_LT(six.q.angularDistance(expected), 1e-12);
  // The same pose as a 4x4, with brackets and line breaks (as numpy prints it).
  const Eigen::Matrix4d m = six.Matrix();
  std::ostringstream text;
  text << "[[" << m(0, 0) << ", " << m(0, 1) << ", " << m(0, 2) << ", " << m(0, 3) << "],\n";
  for (int i = 1; i < 4; ++i) {
    text << " [" << m(i, 0) << " " << m(i, 1) << " " << m(i, 2) << " " << m(i, 3) << "]\n";
  }
  text << "]";
  const Pose3d matrix = ParsePoseGuess(text.str(), "guess.txt");
  EXPECT_LT(matrix.q.angularDistance(expected), 1e-5);  // six printed digits
  EXPECT_LT((matrix.p - six.p).norm(), 1e-12);
  // Errors name the problem.
  const auto message = [](const std::string& t) {
    try {
      ParsePoseGuess(t, "--init");
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_NE(message("1,2,3").find("expected 6 numbers"), std::string::npos);
  EXPECT_NE(message("1,2,x,0,0,0").find("--init:1:5: 'x' (number 3)"), std::string::npos);
  EXPECT_NE(message("1 0 0 0\n0 1 0 O\n0 0 1 0\n0 0 0 1").find("--init:2:7: 'O' (number 8)"),
            std::string::npos);
  EXPECT_NE(message("1 0 0 0  0 1 0 0  0 0 1 0  0 0 1 1").find("last row"), std::string::npos);
  EXPECT_NE(message("2 0 0 0  0 1 0 0  0 0 1 0  0 0 0 1").find("not a rotation"),
            std::string::npos);
  EXPECT_NE(message("-1 0 0 0  0 1 0 0  0 0 1 0  0 0 0 1").find("not a rotation"),
            std::string::npos);
}

class RegistrationOnSimulatedScans : public ::testing::Test {
 protected:
  void SetUp() override {
    const test::Scene scene = test::MakeStreetScene(51);
    test::ScanPattern pattern;
    pattern.range_noise_m = 0.02;
    std::mt19937_64 rng(52);
    const Pose3d T_W_target = test::MakePose(0.0, 0.0, 1.8, 0.0, 0.0, 0.0);
    const Pose3d T_W_source = test::MakePose(0.9, 0.1, 1.8, -2.0, 0.2, 0.1);
    target_ = test::SimulateStaticSweep(scene, T_W_target, pattern, &rng);
    source_ = test::SimulateStaticSweep(scene, T_W_source, pattern, &rng);
    truth_ = T_W_target.Inverse() * T_W_source;
  }
  PointCloud source_;
  PointCloud target_;
  Pose3d truth_;
};

TEST_F(RegistrationOnSimulatedScans, BothMethodsAndEveryLossRecoverTheMotion) {
  for (const char* method : {"point_to_plane", "point_to_point"}) {
    for (const char* loss : {"none", "huber", "cauchy"}) {
      // Point-to-point residuals are centroid-to-centroid distances of about a voxel, so
      // its loss scale is a voxel; point-to-plane residuals are at the noise level.
      const bool plane = std::string(method) == "point_to_plane";
      RegistrationOptions setting =
          MakeRegistrationOptions(method, loss, plane ? 0.1 : 0.25, 0.25, 1.0);
      // The street's 0.3 m poles collapse to lines at 0.25 m voxels: no plane there.
      setting.icp.min_target_planarity = 0.5;
      // Point-to-point converges linearly (each closed-form step only follows the current
      // matches), point-to-plane quadratically near the solution.
      setting.icp.convergence.max_iterations = 100;
      const RegistrationResult result =
          RegisterPointClouds(source_, target_, Pose3d::Identity(), setting);
      // Point-to-point matches voxel centroids, which are not the same physical points in
      // the two scans: its error is bounded by the sampling (a fraction of the 0.25 m
      // voxel), point-to-plane's by the noise.
      EXPECT_LT(geometry::TranslationError(result.icp.T_target_source, truth_), plane ? 0.01 : 0.1)
          << method << " " << loss;
      EXPECT_LT(test::RotationErrorDeg(result.icp.T_target_source, truth_), plane ? 0.1 : 0.5)
          << method << " " << loss;
      EXPECT_GT(result.source_points, 1000);
      EXPECT_LT(result.source_points, source_.size());
      EXPECT_GT(result.time_s, 0.0);
    }
  }
}

TEST_F(RegistrationOnSimulatedScans, ReportAndYamlCarryTheResult) {
  const RegistrationOptions setting =
      MakeRegistrationOptions("point_to_plane", "cauchy", 0.15, 0.25, 1.0);
  const RegistrationResult result =
      RegisterPointClouds(source_, target_, Pose3d::Identity(), setting);
  const std::string report = FormatRegistrationReport(result, setting);
  for (const char* key : {"T_target_source", "inlier RMSE", "iterations", "time", "covariance"}) {
    EXPECT_NE(report.find(key), std::string::npos) << key << " missing from\n" << report;
  }
  const YAML::Node yaml = YAML::Load(FormatRegistrationYaml(result, setting));
  Eigen::Matrix4d T;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) T(r, c) = yaml["T_target_source"][r][c].as<double>();
  }
  EXPECT_TRUE(T.isApprox(result.icp.T_target_source.Matrix(), 1e-10)) << T;
  Eigen::Matrix<double, 6, 6> covariance;
  for (int r = 0; r < 6; ++r) {
    for (int c = 0; c < 6; ++c) covariance(r, c) = yaml["covariance"][r][c].as<double>();
  }
  EXPECT_TRUE(covariance.isApprox(result.icp.covariance, 1e-10));
  EXPECT_EQ(yaml["loss"].as<std::string>(), "cauchy");
  EXPECT_EQ(yaml["iterations"].as<int>(), result.icp.iterations);
  EXPECT_NEAR(yaml["inlier_rmse_m"].as<double>(), result.icp.inlier_rmse_m, 1e-12);
  EXPECT_EQ(yaml["q_xyzw"].size(), 4u);
}

TEST_F(RegistrationOnSimulatedScans, BadInputGetsClearErrors) {
  const RegistrationOptions setting;
  EXPECT_THROW(RegisterPointClouds(PointCloud(), target_, Pose3d::Identity(), setting), Error);
  EXPECT_THROW(RegisterPointClouds(source_, PointCloud(), Pose3d::Identity(), setting), Error);
  PointCloud bad = source_;
  bad.points(2, 7) = std::nan("");
  EXPECT_THROW(RegisterPointClouds(bad, target_, Pose3d::Identity(), setting), Error);
  EXPECT_NO_THROW(RegisterPointClouds(RemoveNonFinite(bad), target_, Pose3d::Identity(), setting));
}

}  // namespace
}  // namespace lidar
}  // namespace autocal
