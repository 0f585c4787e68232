#include "autocal/geometry/manifolds.h"

#include <ceres/ceres.h>
#include <ceres/gradient_checker.h>
#include <ceres/manifold_test_utils.h>
#include <gtest/gtest.h>

#include <random>

#include "autocal/geometry/so3.h"

namespace autocal {
namespace geometry {
namespace {

constexpr double kTolerance = 1e-9;

// Ceres' invariant macro names its helpers unqualified, so it runs inside this function.
void ExpectManifoldInvariants(const ceres::Manifold& manifold, const ceres::Vector& x,
                              const ceres::Vector& delta, const ceres::Vector& y) {
  using namespace ceres;  // NOLINT(build/namespaces)
  EXPECT_THAT_MANIFOLD_INVARIANTS_HOLD(manifold, x, delta, y, kTolerance);
}

Eigen::Vector3d RandomVector(std::mt19937* rng, double scale) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  return scale * Eigen::Vector3d(u(*rng), u(*rng), u(*rng));
}

TEST(RightQuaternionManifold, InvariantsHold) {
  std::mt19937 rng(11);
  const RightQuaternionManifold manifold;
  for (int trial = 0; trial < 30; ++trial) {
    const Eigen::Quaterniond x = Eigen::Quaterniond::UnitRandom();
    const Eigen::Quaterniond y = Eigen::Quaterniond::UnitRandom();
    // Small, moderate and near-pi steps.
    const double scale = trial % 3 == 0 ? 1e-6 : (trial % 3 == 1 ? 0.5 : 1.7);
    const Eigen::Vector3d delta = RandomVector(&rng, scale);
    ExpectManifoldInvariants(manifold, x.coeffs(), delta, y.coeffs());
  }
}

TEST(RightQuaternionManifold, PlusPerturbsInTheBodyFrame) {
  const RightQuaternionManifold manifold;
  const Eigen::Quaterniond x = Eigen::Quaterniond::UnitRandom();
  const Eigen::Vector3d delta(0.1, -0.2, 0.05);
  Eigen::Quaterniond out;
  manifold.Plus(x.coeffs().data(), delta.data(), out.coeffs().data());
  EXPECT_LT(AngularDistance(out, Eigen::Quaterniond(x * Exp(delta))), 1e-15);
}

TEST(PoseManifold, InvariantsHold) {
  std::mt19937 rng(12);
  const PoseManifold manifold;
  for (int trial = 0; trial < 10; ++trial) {
    Eigen::Matrix<double, 7, 1> x, y;
    x << Eigen::Quaterniond::UnitRandom().coeffs(), RandomVector(&rng, 10.0);
    y << Eigen::Quaterniond::UnitRandom().coeffs(), RandomVector(&rng, 10.0);
    Eigen::Matrix<double, 6, 1> delta;
    delta << RandomVector(&rng, 0.3), RandomVector(&rng, 2.0);
    ExpectManifoldInvariants(manifold, x, delta, y);
  }
}

// An analytic cost r(q) = R(q) v - target whose tangent Jacobian -R Hat(v) is lifted to
// ambient coordinates with LiftTangentJacobian; GradientChecker must accept it.
class RotatedVectorCost final : public ceres::SizedCostFunction<3, 4> {
 public:
  RotatedVectorCost(const Eigen::Vector3d& v, const Eigen::Vector3d& target)
      : v_(v), target_(target) {}
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const Eigen::Map<const Eigen::Quaterniond> q(parameters[0]);
    Eigen::Map<Eigen::Vector3d> r(residuals);
    r = q * v_ - target_;
    if (jacobians != nullptr && jacobians[0] != nullptr) {
      const Eigen::Matrix3d j_tangent = -q.toRotationMatrix() * Hat(v_);
      Eigen::Map<Eigen::Matrix<double, 3, 4, Eigen::RowMajor>> j(jacobians[0]);
      j = LiftTangentJacobian<3>(j_tangent, parameters[0]);
    }
    return true;
  }

 private:
  Eigen::Vector3d v_, target_;
};

TEST(LiftTangentJacobian, PassesGradientChecker) {
  std::mt19937 rng(13);
  for (int trial = 0; trial < 20; ++trial) {
    const RotatedVectorCost cost(RandomVector(&rng, 3.0), RandomVector(&rng, 3.0));
    const RightQuaternionManifold manifold;
    const std::vector<const ceres::Manifold*> manifolds = {&manifold};
    ceres::NumericDiffOptions options;
    const ceres::GradientChecker checker(&cost, &manifolds, options);
    Eigen::Quaterniond q = Eigen::Quaterniond::UnitRandom();
    const double* parameters[] = {q.coeffs().data()};
    ceres::GradientChecker::ProbeResults results;
    EXPECT_TRUE(checker.Probe(parameters, 1e-8, &results)) << results.error_log;
  }
}

// The single-row lifts equal the matrix one: LiftTangentRow for a row a, LiftRotatedTangentRow
// for a = (R(q)^T b)^T given b.
TEST(LiftTangentRow, MatchesTheMatrixLift) {
  std::mt19937 rng(17);
  for (int trial = 0; trial < 50; ++trial) {
    const Eigen::Quaterniond q(Eigen::Quaterniond::UnitRandom());
    const Eigen::Vector3d b = RandomVector(&rng, 4.0);
    const Eigen::Vector3d a = q.conjugate() * b;
    const Eigen::Matrix<double, 1, 4> expected =
        LiftTangentJacobian<1>(a.transpose(), q.coeffs().data());
    Eigen::Matrix<double, 1, 4> row, rotated;
    LiftTangentRow(a.transpose(), q.coeffs().data(), row.data());
    LiftRotatedTangentRow(b, q.coeffs().data(), rotated.data());
    EXPECT_LT((row - expected).norm(), 1e-12 * expected.norm()) << trial;
    EXPECT_LT((rotated - expected).norm(), 1e-12 * expected.norm()) << trial;
  }
}

}  // namespace
}  // namespace geometry
}  // namespace autocal
