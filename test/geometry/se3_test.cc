#include "autocal/geometry/se3.h"

#include <gtest/gtest.h>

#include <random>

namespace autocal {
namespace geometry {
namespace {

Pose3d RandomPose(std::mt19937* rng) {
  std::uniform_real_distribution<double> u(-5.0, 5.0);
  return Pose3d(Eigen::Quaterniond::UnitRandom(), Eigen::Vector3d(u(*rng), u(*rng), u(*rng)));
}

TEST(Se3, InverseAndCompositionFollowTheFrameConvention) {
  std::mt19937 rng(3);
  for (int i = 0; i < 50; ++i) {
    const Pose3d T_a_b = RandomPose(&rng);
    const Pose3d T_b_c = RandomPose(&rng);
    const Eigen::Vector3d p_c(0.5, -2.0, 1.0);
    // p_a = T_a_b * (T_b_c * p_c) = (T_a_b * T_b_c) * p_c
    EXPECT_TRUE(((T_a_b * T_b_c) * p_c).isApprox(T_a_b * (T_b_c * p_c), 1e-12));
    EXPECT_TRUE((T_a_b.Inverse() * (T_a_b * p_c)).isApprox(p_c, 1e-12));
    EXPECT_TRUE((T_a_b.Matrix() * T_b_c.Matrix()).isApprox((T_a_b * T_b_c).Matrix(), 1e-12));
  }
}

TEST(Se3, MatrixRoundTrip) {
  std::mt19937 rng(4);
  const Pose3d pose = RandomPose(&rng);
  const Pose3d back = Pose3d::FromMatrix(pose.Matrix());
  EXPECT_LT(RotationErrorRad(pose, back), 1e-12);
  EXPECT_LT(TranslationError(pose, back), 1e-12);
}

TEST(Se3, ExpAndLogAreInverse) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (double angle : {0.0, 1e-9, 1e-4, 0.5, 2.0, 3.1}) {
    for (int i = 0; i < 10; ++i) {
      Vector6<double> xi;
      xi.head<3>() = 3.0 * Eigen::Vector3d(u(rng), u(rng), u(rng));
      xi.tail<3>() = angle * Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
      const Vector6<double> back = LogSE3(ExpSE3(xi));
      EXPECT_TRUE(back.isApprox(xi, 1e-9) || (back - xi).norm() < 1e-12)
          << "xi = " << xi.transpose() << "\nback = " << back.transpose();
    }
  }
}

// For pure translation Exp is a translation, and the one-parameter subgroup Exp(t xi) is
// the screw motion: Exp(xi) = Exp(xi/2) * Exp(xi/2).
TEST(Se3, ExpIsAOneParameterSubgroup) {
  Vector6<double> xi;
  xi << 1.0, -2.0, 0.5, 0.3, 0.2, -0.9;
  const Pose3d half = ExpSE3<double>(0.5 * xi);
  const Pose3d full = ExpSE3(xi);
  EXPECT_LT(RotationErrorRad(half * half, full), 1e-12);
  EXPECT_LT(TranslationError(half * half, full), 1e-12);
  Vector6<double> translation = Vector6<double>::Zero();
  translation.head<3>() << 1.0, 2.0, 3.0;
  EXPECT_TRUE(ExpSE3(translation).p.isApprox(Eigen::Vector3d(1.0, 2.0, 3.0)));
}

}  // namespace
}  // namespace geometry
}  // namespace autocal
