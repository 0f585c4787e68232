#include "pipeline/calibration_blocks.h"

#include <cmath>
#include <memory>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "autocal/geometry/so3.h"

namespace autocal {
namespace pipeline {
namespace {

CalibrationBlock VectorBlock(double* data, const Eigen::Vector3d& prior, double prior_sigma,
                             double limit) {
  CalibrationBlock b;
  b.name = "T_I_L translation";
  b.data = data;
  b.size = 3;
  b.prior = prior;
  b.prior_sigma = Eigen::Vector3d::Constant(prior_sigma);
  b.max_observable_sigma = limit;
  b.direction_names = {"x", "y", "z"};
  b.display_scale = 100.0;
  b.display_unit = "cm";
  return b;
}

// Eq. (C1) on a Gaussian with a known covariance: the unobservable z is set to its prior and
// x, correlated with it, moves by S_xz / S_zz times z's correction; y, uncorrelated, stays.
TEST(CalibrationBlocks, HoldsUnobservableDirectionsAndConditionsTheRest) {
  Eigen::Vector3d p(0.31, -0.05, 0.60);
  const std::vector<CalibrationBlock> blocks = {
      VectorBlock(p.data(), Eigen::Vector3d(0.30, -0.05, 0.55), 0.3, 0.03)};
  BlockCovariance covariance;
  covariance.ok = true;
  covariance.offsets = {0};
  covariance.matrix = Eigen::Matrix3d::Zero();
  covariance.matrix(0, 0) = 1e-4;   // sigma 1 cm: observable
  covariance.matrix(1, 1) = 1.6e-3;  // sigma 4 cm: informed (prior 30 cm), above the 3 cm limit
  covariance.matrix(2, 2) = 4e-2;   // sigma 20 cm: over half the prior's, held
  covariance.matrix(0, 2) = covariance.matrix(2, 0) = 5e-4;
  const BlockObservability result = HoldUnobservableDirections(blocks, covariance);
  // Eq. C1-C2 with the gain K = 5e-4 / 4e-2 from z to x; z is held at a nominal value whose
  // error has the prior's variance 0.3^2, which K carries into x.
  const double gain = 5e-4 / 4e-2;
  EXPECT_DOUBLE_EQ(p.z(), 0.55);
  EXPECT_NEAR(p.x(), 0.31 - gain * (0.60 - 0.55), 1e-12);
  EXPECT_DOUBLE_EQ(p.y(), -0.05);
  ASSERT_EQ(result.observable.size(), 1u);
  EXPECT_THAT(result.observable[0], ::testing::ElementsAre(true, false, false));
  EXPECT_NEAR(result.sigma[0](0), std::sqrt(1e-4 - gain * 5e-4 + gain * gain * 0.09), 1e-12);
  EXPECT_DOUBLE_EQ(result.sigma[0](1), 0.04);  // kept with its own sigma
  EXPECT_DOUBLE_EQ(result.sigma[0](2), 0.3);   // the prior's
  ASSERT_EQ(result.warnings.size(), 2u);
  EXPECT_THAT(result.warnings[0], ::testing::HasSubstr("y: only partly determined by the drive"));
  EXPECT_THAT(result.warnings[1], ::testing::HasSubstr("z: not excited by the drive"));
}

// A direction whose posterior is barely narrower than its prior is unobservable too, even
// when the prior itself is tighter than the limit.
TEST(CalibrationBlocks, ADirectionTheDataDidNotNarrowIsUnobservable) {
  Eigen::Vector3d p(0.30, -0.05, 0.55);
  const std::vector<CalibrationBlock> blocks = {
      VectorBlock(p.data(), p, 0.02, 0.03)};
  BlockCovariance covariance;
  covariance.ok = true;
  covariance.offsets = {0};
  covariance.matrix = Eigen::Vector3d(1e-6, 1e-6, 0.019 * 0.019).asDiagonal();
  const BlockObservability result = HoldUnobservableDirections(blocks, covariance);
  EXPECT_THAT(result.observable[0], ::testing::ElementsAre(true, true, false));
}

// Under a weak prior (30 cm) a direction the data narrowed to 13 cm is still held: above four
// times its 3 cm limit it is too weak to be worth more than the nominal value. At 11 cm it is
// kept as partly determined.
TEST(CalibrationBlocks, ADirectionFarAboveItsLimitIsHeldUnderAWeakPrior) {
  Eigen::Vector3d p(0.30, -0.05, 0.55);
  const std::vector<CalibrationBlock> blocks = {VectorBlock(p.data(), p, 0.3, 0.03)};
  BlockCovariance covariance;
  covariance.ok = true;
  covariance.offsets = {0};
  covariance.matrix = Eigen::Vector3d(1e-6, 0.11 * 0.11, 0.13 * 0.13).asDiagonal();
  const BlockObservability result = HoldUnobservableDirections(blocks, covariance);
  EXPECT_THAT(result.observable[0], ::testing::ElementsAre(true, false, false));
  ASSERT_EQ(result.warnings.size(), 2u);
  EXPECT_THAT(result.warnings[0], ::testing::HasSubstr("y: only partly determined"));
  EXPECT_THAT(result.warnings[1], ::testing::HasSubstr("z: not excited by the drive"));
  EXPECT_DOUBLE_EQ(result.sigma[0](2), 0.3);
}

TEST(CalibrationBlocks, NamesExcitedDirectionsFarFromTheirPrior) {
  Eigen::Vector3d p(0.30, -0.05, 0.55);
  std::vector<CalibrationBlock> blocks = {VectorBlock(p.data(), p, 0.05, 0.03)};
  const BlockCovariance none;  // not computed: every direction is judged
  EXPECT_TRUE(ImplausibleDirections(blocks, none, 5.0).empty());
  p.y() += 0.3;  // 6 prior sigmas
  EXPECT_THAT(ImplausibleDirections(blocks, none, 5.0),
              ::testing::ElementsAre(::testing::HasSubstr("y moved 30 cm")));
  p.x() = std::nan("");
  EXPECT_EQ(ImplausibleDirections(blocks, none, 5.0).size(), 2u);

  // A direction the drive did not excite wanders within its flat cost and is held at its
  // prior afterwards: it is not judged.
  p.x() = 0.30;
  BlockCovariance covariance;
  covariance.ok = true;
  covariance.offsets = {0};
  covariance.matrix = Eigen::Vector3d(1e-6, 0.04 * 0.04, 1e-6).asDiagonal();
  EXPECT_TRUE(ImplausibleDirections(blocks, covariance, 5.0).empty());
  covariance.matrix(1, 1) = 1e-6;  // excited: judged
  EXPECT_EQ(ImplausibleDirections(blocks, covariance, 5.0).size(), 1u);
}

// Rotation blocks work in the tangent of the right perturbation.
TEST(CalibrationBlocks, RotationBlocksUseTheTangent) {
  const Eigen::Quaterniond nominal = geometry::Exp(Eigen::Vector3d(0.1, -0.2, 0.3));
  Eigen::Quaterniond q = nominal * geometry::Exp(Eigen::Vector3d(0.0, 0.0, 0.2));
  CalibrationBlock b;
  b.name = "T_I_L rotation";
  b.data = q.coeffs().data();
  b.size = 3;
  b.rotation = true;
  b.prior = nominal.coeffs();
  b.prior_sigma = Eigen::Vector3d::Constant(0.05);
  b.max_observable_sigma = 0.01;
  b.direction_names = {"roll", "pitch", "yaw"};
  b.display_scale = 180.0 / M_PI;
  b.display_unit = "deg";
  EXPECT_THAT(ImplausibleDirections({b}, BlockCovariance(), 3.0),
              ::testing::ElementsAre(::testing::HasSubstr("yaw")));
  BlockCovariance covariance;
  covariance.ok = true;
  covariance.offsets = {0};
  covariance.matrix = Eigen::Vector3d(1e-6, 1e-6, 1.0).asDiagonal();  // yaw unobservable
  HoldUnobservableDirections({b}, covariance);
  EXPECT_LT(geometry::AngularDistance(q, nominal), 1e-12);
}

}  // namespace
}  // namespace pipeline
}  // namespace autocal
