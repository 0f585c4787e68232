#include "autocal/geometry/so3.h"

#include <ceres/jet.h>
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "autocal/common/units.h"

namespace autocal {
namespace geometry {
namespace {

// Rotation vectors that stress every branch: zero, tiny, moderate, large and near pi.
std::vector<Eigen::Vector3d> TestRotationVectors() {
  std::vector<Eigen::Vector3d> out = {Eigen::Vector3d::Zero()};
  std::mt19937 rng(42);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const std::vector<double> angles = {1e-12, 1e-8, 1e-5, 1e-3,       0.1,
                                      1.0,   2.5,  3.0,  kPi - 1e-3, kPi - 1e-7};
  for (double angle : angles) {
    for (int i = 0; i < 5; ++i) {
      const Eigen::Vector3d axis = Eigen::Vector3d(unit(rng), unit(rng), unit(rng)).normalized();
      out.push_back(angle * axis);
    }
  }
  return out;
}

TEST(So3, HatIsCrossProductAndVeeInvertsIt) {
  const Eigen::Vector3d a(0.3, -1.2, 2.0), b(-0.7, 0.1, 0.5);
  EXPECT_TRUE((Hat(a) * b).isApprox(a.cross(b), 1e-15));
  EXPECT_TRUE(Vee(Hat(a)).isApprox(a, 1e-15));
  EXPECT_TRUE((Hat(a) + Hat(a).transpose()).isZero(0.0));
}

TEST(So3, ExpMatchesAngleAxis) {
  for (const Eigen::Vector3d& phi : TestRotationVectors()) {
    const double angle = phi.norm();
    const Eigen::Matrix3d expected = angle > 0
                                         ? Eigen::AngleAxisd(angle, phi / angle).toRotationMatrix()
                                         : Eigen::Matrix3d::Identity();
    EXPECT_TRUE(ExpMatrix(phi).isApprox(expected, 1e-12)) << "phi = " << phi.transpose();
    EXPECT_NEAR(Exp(phi).norm(), 1.0, 1e-15);
  }
}

TEST(So3, LogInvertsExpUpToPi) {
  for (const Eigen::Vector3d& phi : TestRotationVectors()) {
    const Eigen::Vector3d back = Log(Exp(phi));
    EXPECT_LT((back - phi).norm(), 1e-12 * std::max(1.0, phi.norm()))
        << "phi = " << phi.transpose() << " back = " << back.transpose();
  }
}

TEST(So3, ExpInvertsLogForAnyQuaternionSign) {
  std::mt19937 rng(7);
  for (int i = 0; i < 200; ++i) {
    Eigen::Quaterniond q = Eigen::Quaterniond::UnitRandom();
    if (i % 2) q.coeffs() = -q.coeffs();
    const Eigen::Vector3d phi = Log(q);
    EXPECT_LE(phi.norm(), kPi + 1e-12);
    EXPECT_LT(AngularDistance(Exp(phi), q), 1e-12);
  }
}

TEST(So3, LogAtExactlyPiHasAnglePi) {
  const Eigen::Quaterniond q(0.0, 0.0, 0.0, 1.0);  // w = 0: 180 deg about z
  const Eigen::Vector3d phi = Log(q);
  EXPECT_NEAR(phi.norm(), kPi, 1e-15);
  EXPECT_NEAR(std::abs(phi.z()), kPi, 1e-15);
}

// Jr(phi) dphi ~= Log(Exp(phi)^-1 Exp(phi + dphi)), checked by central differences.
TEST(So3, RightJacobianMatchesNumericDerivative) {
  const double h = 1e-6;
  for (const Eigen::Vector3d& phi : TestRotationVectors()) {
    if (phi.norm() > kPi - 1e-2) continue;  // Log wraps at pi; derivative taken below it
    Eigen::Matrix3d numeric;
    for (int i = 0; i < 3; ++i) {
      const Eigen::Vector3d d = h * Eigen::Vector3d::Unit(i);
      const Eigen::Quaterniond q_inv = Exp(phi).conjugate();
      numeric.col(i) = (Log(Eigen::Quaterniond(q_inv * Exp(Eigen::Vector3d(phi + d)))) -
                        Log(Eigen::Quaterniond(q_inv * Exp(Eigen::Vector3d(phi - d))))) /
                       (2 * h);
    }
    EXPECT_TRUE(RightJacobian(phi).isApprox(numeric, 1e-7))
        << "phi = " << phi.transpose() << "\nanalytic\n"
        << RightJacobian(phi) << "\nnumeric\n"
        << numeric;
  }
}

TEST(So3, LeftJacobianIsRotatedRightJacobian) {
  for (const Eigen::Vector3d& phi : TestRotationVectors()) {
    EXPECT_TRUE(LeftJacobian(phi).isApprox(ExpMatrix(phi) * RightJacobian(phi), 1e-12));
  }
}

TEST(So3, JacobianInversesAreInverses) {
  for (const Eigen::Vector3d& phi : TestRotationVectors()) {
    EXPECT_TRUE((RightJacobian(phi) * RightJacobianInverse(phi)).isIdentity(1e-9))
        << "phi = " << phi.transpose();
    EXPECT_TRUE((LeftJacobian(phi) * LeftJacobianInverse(phi)).isIdentity(1e-9))
        << "phi = " << phi.transpose();
  }
}

// With ceres::Jet the templated functions must give finite, correct derivatives, also at
// phi = 0 where a naive sqrt would produce infinities: d Log(Exp(phi))/d phi = I.
TEST(So3, JetDerivativesAreFiniteAndCorrect) {
  using Jet = ceres::Jet<double, 3>;
  for (const Eigen::Vector3d& phi : TestRotationVectors()) {
    if (phi.norm() > kPi - 1e-2) continue;
    Vector3<Jet> phi_jet;
    for (int i = 0; i < 3; ++i) phi_jet(i) = Jet(phi(i), i);
    const Vector3<Jet> back = Log(Exp(phi_jet));
    for (int i = 0; i < 3; ++i) {
      EXPECT_NEAR(back(i).a, phi(i), 1e-12);
      for (int j = 0; j < 3; ++j) {
        EXPECT_NEAR(back(i).v(j), i == j ? 1.0 : 0.0, 1e-9) << "phi = " << phi.transpose();
      }
    }
    // The derivative of Exp(phi) * v equals -R Hat(v) Jr(phi).
    const Eigen::Vector3d v(0.4, -1.1, 0.3);
    const Vector3<Jet> rotated = Exp(phi_jet) * v.cast<Jet>();
    Eigen::Matrix3d jet_jacobian;
    for (int i = 0; i < 3; ++i) jet_jacobian.row(i) = rotated(i).v.transpose();
    const Eigen::Matrix3d expected = -ExpMatrix(phi) * Hat(v) * RightJacobian(phi);
    EXPECT_TRUE(jet_jacobian.isApprox(expected, 1e-9)) << "phi = " << phi.transpose();
  }
}

}  // namespace
}  // namespace geometry
}  // namespace autocal
