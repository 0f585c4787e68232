#include "autocal/estimation/calibration_observability.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>

#include "autocal/common/error.h"
#include "autocal/common/units.h"
#include "autocal/factors/loss.h"
#include "autocal/geometry/manifolds.h"
#include "autocal/geometry/so3.h"

namespace autocal {
namespace estimation {
namespace {

EstimatedBlock VectorBlock(double* data, const Eigen::Vector3d& prior, double prior_sigma,
                           double limit) {
  EstimatedBlock b;
  b.id = sensors::CalibrationBlockId::kLidarTranslation;
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
TEST(CalibrationObservability, HoldsUnobservableDirectionsAndConditionsTheRest) {
  Eigen::Vector3d p(0.31, -0.05, 0.60);
  const std::vector<EstimatedBlock> blocks = {
      VectorBlock(p.data(), Eigen::Vector3d(0.30, -0.05, 0.55), 0.3, 0.03)};
  BlockCovariance covariance;
  covariance.ok = true;
  covariance.offsets = {0};
  covariance.matrix = Eigen::Matrix3d::Zero();
  covariance.matrix(0, 0) = 1e-4;    // sigma 1 cm: observable
  covariance.matrix(1, 1) = 1.6e-3;  // sigma 4 cm: informed (prior 30 cm), above the 3 cm limit
  covariance.matrix(2, 2) = 4e-2;    // sigma 20 cm: over half the prior's, held
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

// A block at its prior (sigma 2 cm, limit 3 cm) whose x and y the data determine to 1 mm and
// z to z_sigma_m, through HoldUnobservableDirections.
BlockObservability HeldWithZSigma(double z_sigma_m) {
  Eigen::Vector3d p(0.30, -0.05, 0.55);
  const std::vector<EstimatedBlock> blocks = {VectorBlock(p.data(), p, 0.02, 0.03)};
  BlockCovariance covariance;
  covariance.ok = true;
  covariance.offsets = {0};
  covariance.matrix = Eigen::Vector3d(1e-6, 1e-6, z_sigma_m * z_sigma_m).asDiagonal();
  return HoldUnobservableDirections(blocks, covariance);
}

// A direction whose posterior is barely narrower than its prior is unobservable too, even
// when the prior itself is tighter than the limit.
TEST(CalibrationObservability, ADirectionTheDataDidNotNarrowIsUnobservable) {
  const BlockObservability result = HeldWithZSigma(0.019);
  EXPECT_THAT(result.observable[0], ::testing::ElementsAre(true, true, false));
  ASSERT_EQ(result.warnings.size(), 1u);
  EXPECT_THAT(result.warnings[0],
              ::testing::HasSubstr("(sigma 1.9 cm after the solve, prior 2 cm)"));
}

// With the exact Hessian (Eq. C5) a direction can come out wider than its prior: the data's
// own information about it is not positive, and the warning says so.
TEST(CalibrationObservability, ADirectionWiderThanItsPriorIsNamedSo) {
  const BlockObservability result = HeldWithZSigma(0.05);
  EXPECT_THAT(result.observable[0], ::testing::ElementsAre(true, true, false));
  EXPECT_DOUBLE_EQ(result.sigma[0](2), 0.02);
  ASSERT_EQ(result.warnings.size(), 1u);
  EXPECT_THAT(result.warnings[0],
              ::testing::HasSubstr("(sigma 5 cm after the solve, prior 2 cm: alone, the data "
                                   "would not hold it anywhere); held at"));
}

// Under a weak prior (30 cm) a direction the data narrowed to 13 cm is still held: above four
// times its 3 cm limit it is too weak to be worth more than the nominal value. At 11 cm it is
// kept as partly determined.
TEST(CalibrationObservability, ADirectionFarAboveItsLimitIsHeldUnderAWeakPrior) {
  Eigen::Vector3d p(0.30, -0.05, 0.55);
  const std::vector<EstimatedBlock> blocks = {VectorBlock(p.data(), p, 0.3, 0.03)};
  BlockCovariance covariance;
  covariance.ok = true;
  covariance.offsets = {0};
  covariance.matrix = Eigen::Vector3d(1e-6, 0.11 * 0.11, 0.13 * 0.13).asDiagonal();
  const BlockObservability result = HoldUnobservableDirections(blocks, covariance);
  EXPECT_THAT(result.observable[0], ::testing::ElementsAre(true, false, false));
  ASSERT_EQ(result.warnings.size(), 2u);
  EXPECT_THAT(result.warnings[0], ::testing::HasSubstr("y: only partly determined"));
  // The data did narrow it: the warning says why it is held all the same.
  EXPECT_THAT(result.warnings[1],
              ::testing::HasSubstr("z: determined by the drive too weakly to keep (sigma 13 cm "
                                   "after the solve, above 4 times its limit of 3 cm; prior "
                                   "30 cm); held at the nominal value"));
  EXPECT_DOUBLE_EQ(result.sigma[0](2), 0.3);
}

TEST(CalibrationObservability, NamesInformedDirectionsFarFromTheirPrior) {
  Eigen::Vector3d p(0.30, -0.05, 0.55);
  std::vector<EstimatedBlock> blocks = {VectorBlock(p.data(), p, 0.05, 0.03)};
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

  // Under a 30 cm prior a direction the data narrowed to 10 cm is only partly determined
  // (above the 3 cm limit, within four times it): its estimate is kept, so it is judged.
  const Eigen::Vector3d nominal(0.30, -0.05, 0.55);
  Eigen::Vector3d wide = nominal + Eigen::Vector3d(0.0, 1.8, 0.0);  // 6 prior sigmas
  const std::vector<EstimatedBlock> kept = {VectorBlock(wide.data(), nominal, 0.3, 0.03)};
  covariance.matrix = Eigen::Vector3d(1e-6, 0.1 * 0.1, 1e-6).asDiagonal();
  EXPECT_THAT(ImplausibleDirections(kept, covariance, 5.0),
              ::testing::ElementsAre(::testing::HasSubstr("y moved 180 cm")));
  covariance.matrix(1, 1) = 0.2 * 0.2;  // left at its prior: held, not judged
  EXPECT_TRUE(ImplausibleDirections(kept, covariance, 5.0).empty());
}

// Under a stated prior (1 cm) a direction the data narrowed to 6.4 mm is held (above half the
// prior's sigma), yet the data hold 1.4 times the prior's information: 9 prior sigmas away,
// the drive contradicts the stated value, and it is judged. Under a weak default prior it is
// not, nor a direction the data leave nearly flat (posterior above 0.9 of the prior's sigma),
// nor one determined more weakly than 4 times its limit.
TEST(CalibrationObservability, JudgesAHeldDirectionTheDataContradictUnderAStatedPrior) {
  const Eigen::Vector3d nominal(-1.0, 0.05, 0.7);
  Eigen::Vector3d p = nominal + Eigen::Vector3d(-0.09, 0.0, 0.0);
  std::vector<EstimatedBlock> blocks = {VectorBlock(p.data(), nominal, 0.01, 0.02)};
  blocks[0].prior_stated = true;
  BlockCovariance covariance;
  covariance.ok = true;
  covariance.offsets = {0};
  covariance.matrix = Eigen::Vector3d(0.0064 * 0.0064, 1e-6, 0.0095 * 0.0095).asDiagonal();
  ASSERT_FALSE(HoldUnobservableDirections(blocks, covariance).observable[0][0]);  // held
  p = nominal + Eigen::Vector3d(-0.09, 0.0, 0.0);  // the hold moved it: back to the solve's
  EXPECT_THAT(ImplausibleDirections(blocks, covariance, 5.0),
              ::testing::ElementsAre(::testing::HasSubstr("x moved -9 cm")));
  p.x() = nominal.x() - 0.04;  // 4 prior sigmas: plausible
  EXPECT_TRUE(ImplausibleDirections(blocks, covariance, 5.0).empty());
  p.x() = nominal.x() - 0.09;
  blocks[0].prior_stated = false;  // a weak default: held, not judged
  EXPECT_TRUE(ImplausibleDirections(blocks, covariance, 5.0).empty());
  blocks[0].prior_stated = true;
  p.z() = nominal.z() + 0.09;  // posterior 0.95 of the prior's sigma: nearly flat, not judged
  EXPECT_THAT(ImplausibleDirections(blocks, covariance, 5.0),
              ::testing::ElementsAre(::testing::HasSubstr("x moved")));
  blocks[0].max_observable_sigma = 0.001;  // 6.4 mm is above 4 times a 1 mm limit
  EXPECT_TRUE(ImplausibleDirections(blocks, covariance, 5.0).empty());
}

// Rotation blocks work in the tangent of the right perturbation.
TEST(CalibrationObservability, RotationBlocksUseTheTangent) {
  const Eigen::Quaterniond nominal = geometry::Exp(Eigen::Vector3d(0.1, -0.2, 0.3));
  Eigen::Quaterniond q = nominal * geometry::Exp(Eigen::Vector3d(0.0, 0.0, 0.2));
  EstimatedBlock b;
  b.id = sensors::CalibrationBlockId::kLidarRotation;
  b.name = "T_I_L rotation";
  b.data = q.coeffs().data();
  b.size = 3;
  b.manifold = sensors::BlockManifold::kRightQuaternion;
  b.prior = nominal.coeffs();
  b.prior_sigma = Eigen::Vector3d::Constant(0.05);
  b.max_observable_sigma = 0.01;
  b.direction_names = {"roll", "pitch", "yaw"};
  b.display_scale = kRadToDeg;
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

// A block from the table points into the calibration and carries the table's names.
TEST(CalibrationObservability, BlockOfTakesTheTableRow) {
  sensors::Calibration c;
  const EstimatedBlock rotation = BlockOf(sensors::CalibrationBlockId::kVehicleRotation, &c);
  EXPECT_EQ(rotation.data, c.q_I_V.coeffs().data());
  EXPECT_EQ(rotation.size, 3);
  EXPECT_EQ(rotation.manifold, sensors::BlockManifold::kRightQuaternion);
  EXPECT_EQ(rotation.name, "T_I_V rotation");
  EXPECT_THAT(rotation.direction_names, ::testing::ElementsAre(::testing::HasSubstr("mount roll"),
                                                               ::testing::HasSubstr("mount pitch"),
                                                               ::testing::HasSubstr("mount yaw")));
  EXPECT_DOUBLE_EQ(rotation.display_scale, kRadToDeg);
  const EstimatedBlock track = BlockOf(sensors::CalibrationBlockId::kTrackWidth, &c);
  EXPECT_EQ(track.data, &c.track_width_m);
  EXPECT_EQ(track.size, 1);
  EXPECT_THAT(track.direction_names, ::testing::ElementsAre("track width"));
  EXPECT_EQ(track.display_unit, "mm");
}

// With nothing but their priors, the blocks' joint covariance is the priors' (diagonal, in the
// rotation's tangent), and every direction is then held: the data added nothing.
TEST(CalibrationObservability, PriorsAloneGiveThePriorCovariance) {
  sensors::Calibration c;
  c.q_I_L = geometry::Exp(Eigen::Vector3d(0.1, -0.2, 0.3));
  std::vector<EstimatedBlock> blocks = {BlockOf(sensors::CalibrationBlockId::kLidarRotation, &c),
                                        BlockOf(sensors::CalibrationBlockId::kTrackWidth, &c)};
  blocks[0].prior = c.q_I_L.coeffs();
  blocks[0].prior_sigma = Eigen::Vector3d(0.01, 0.02, 0.03);
  blocks[0].max_observable_sigma = 0.001;
  blocks[1].prior = Eigen::VectorXd::Constant(1, c.track_width_m);
  blocks[1].prior_sigma = Eigen::VectorXd::Constant(1, 0.05);
  blocks[1].max_observable_sigma = 0.005;
  geometry::RightQuaternionManifold manifold;
  ceres::Problem::Options options;
  options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(options);
  problem.AddParameterBlock(c.q_I_L.coeffs().data(), 4, &manifold);
  AddBlockPriors(blocks, factors::LossOptions(), &problem);
  EXPECT_EQ(problem.NumResidualBlocks(), 2);
  const BlockCovariance covariance = ComputeBlockCovariance(blocks, &problem);
  ASSERT_TRUE(covariance.ok);
  EXPECT_THAT(covariance.offsets, ::testing::ElementsAre(0, 3));
  const Eigen::Vector4d variances(1e-4, 4e-4, 9e-4, 2.5e-3);
  EXPECT_TRUE(covariance.matrix.isApprox(Eigen::MatrixXd(variances.asDiagonal()), 1e-9))
      << covariance.matrix;
  const BlockObservability observability = HoldUnobservableDirections(blocks, covariance);
  EXPECT_THAT(observability.observable[0], ::testing::ElementsAre(false, false, false));
  EXPECT_THAT(observability.observable[1], ::testing::ElementsAre(false));
  EXPECT_EQ(observability.warnings.size(), 4u);
}

// A block the problem gives fewer tangent directions than it states (z held by a subset
// manifold) is refused: its third direction would have read the next block's column.
TEST(CalibrationObservability, ABlockOfAnotherTangentSizeIsRefused) {
  Eigen::Vector3d p(0.30, -0.05, 0.55);
  sensors::Calibration c;
  std::vector<EstimatedBlock> blocks = {VectorBlock(p.data(), p, 0.3, 0.05),
                                        BlockOf(sensors::CalibrationBlockId::kTrackWidth, &c)};
  blocks[1].prior = Eigen::VectorXd::Constant(1, c.track_width_m);
  blocks[1].prior_sigma = Eigen::VectorXd::Constant(1, 0.05);
  ceres::SubsetManifold hold_z(3, {2});
  ceres::Problem::Options options;
  options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(options);
  problem.AddParameterBlock(p.data(), 3, &hold_z);
  AddBlockPriors(blocks, factors::LossOptions(), &problem);
  try {
    ComputeBlockCovariance(blocks, &problem);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("T_I_L translation: the problem gives it 2 "
                                               "tangent directions where the block states 3"));
  }
  problem.SetManifold(p.data(), nullptr);
  EXPECT_TRUE(ComputeBlockCovariance(blocks, &problem).ok);
}

// A residual block that cannot be evaluated (a cost function returning false) leaves the
// covariance, the error budget and the rows' scatter not ok; the Jacobian of the failed stretch
// was summed in as an empty matrix of another size before.
struct FailingRow final : public ceres::SizedCostFunction<1, 3> {
  bool Evaluate(double const* const*, double*, double**) const override { return false; }
};

TEST(CalibrationObservability, AResidualThatFailsToEvaluateLeavesTheCovarianceNotOk) {
  Eigen::Vector3d p(0.30, -0.05, 0.55);
  const std::vector<EstimatedBlock> blocks = {VectorBlock(p.data(), p, 0.3, 0.05)};
  ceres::Problem problem;
  AddBlockPriors(blocks, factors::LossOptions(), &problem);
  problem.AddResidualBlock(new FailingRow, nullptr, p.data());
  EXPECT_FALSE(ComputeBlockCovariance(blocks, &problem).ok);
  std::vector<ceres::ResidualBlockId> all;
  problem.GetResidualBlocks(&all);
  EXPECT_FALSE(ComputeErrorBudget(blocks, &problem, {{"all", all}}).ok);
}

// A linear problem: a state s measured against x (as a trajectory is solved with the
// calibration), x + z/2 and y measured, z barely informed. After HoldUnobservableDirections
// moves the calibration (Eq. C1) the state still belongs to the old one; pinning the held z
// and solving again (Eq. C3) gives, for a linear problem, exactly the conditioned x and the
// state that goes with it.
struct LinearRow {
  double weight, a, b, c, d, m;  // weight * (a x + b y + c z + d s - m)
  template <typename T>
  bool operator()(const T* p, const T* s, T* r) const {
    r[0] = T(weight) * (T(a) * p[0] + T(b) * p[1] + T(c) * p[2] + T(d) * s[0] - T(m));
    return true;
  }
};

TEST(CalibrationObservability, SolvingAgainWithTheHeldDirectionsPinnedKeepsTheStateConsistent) {
  Eigen::Vector3d p(0.30, -0.05, 0.55);
  double s = 0.0;
  std::vector<EstimatedBlock> blocks = {
      VectorBlock(p.data(), Eigen::Vector3d(0.30, -0.05, 0.55), 0.3, 0.05)};
  ceres::Problem problem;
  const auto row = [&](const LinearRow& r) {
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<LinearRow, 1, 3, 1>(new LinearRow(r)),
                             nullptr, p.data(), &s);
  };
  row({100.0, 1.0, 0.0, 0.5, 0.0, 0.62});   // x + z/2 = 0.62
  row({100.0, 0.0, 1.0, 0.0, 0.0, -0.02});  // y = -0.02
  row({100.0, -1.0, 0.0, 0.0, 1.0, 1.5});   // s - x = 1.5
  AddBlockPriors(blocks, factors::LossOptions(), &problem);
  ceres::Solver::Options options;
  options.function_tolerance = options.gradient_tolerance = options.parameter_tolerance = 1e-15;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  const BlockCovariance covariance = ComputeBlockCovariance(blocks, &problem);
  ASSERT_TRUE(covariance.ok);
  const BlockObservability observability = HoldUnobservableDirections(blocks, covariance);
  EXPECT_THAT(observability.held[0], ::testing::ElementsAre(false, false, true));
  ASSERT_TRUE(AnyHeld(observability));
  EXPECT_FALSE(AllHeld(observability));  // x and y are determined
  const Eigen::Vector3d conditioned = p;
  EXPECT_DOUBLE_EQ(conditioned.z(), 0.55);
  EXPECT_GT(std::abs((s - p.x()) - 1.5), 1e-3);  // the state belongs to the solve's x

  AddHeldDirectionPriors(blocks, observability, &problem);
  EXPECT_EQ(problem.NumResidualBlocks(), 5);
  ceres::Solve(options, &problem, &summary);
  EXPECT_NEAR(p.z(), 0.55, 1e-9);
  SetHeldDirectionsToPrior(blocks, observability);
  EXPECT_EQ(p.z(), 0.55);
  EXPECT_NEAR(p.x(), conditioned.x(), 1e-9);
  EXPECT_NEAR(p.y(), conditioned.y(), 1e-9);
  EXPECT_NEAR(s - p.x(), 1.5, 1e-4);  // within the row's sigma of 0.01 times the prior's pull
}

// A nonlinear problem with a rotation block, a nuisance state that is marginalized and a robust
// loss: the covariance equals ceres::Covariance's on the same problem.
struct RotatedPointRow {
  Eigen::Vector3d u, m;
  template <typename T>
  bool operator()(const T* q_xyzw, const T* p, const T* s, T* r) const {
    const Eigen::Quaternion<T> q(q_xyzw[3], q_xyzw[0], q_xyzw[1], q_xyzw[2]);
    const Eigen::Matrix<T, 3, 1> predicted = q * u.cast<T>() +
                                             Eigen::Map<const Eigen::Matrix<T, 3, 1>>(p) +
                                             Eigen::Matrix<T, 3, 1>::Constant(s[0]);
    for (int i = 0; i < 3; ++i) r[i] = T(10.0) * (predicted(i) - T(m(i)));
    return true;
  }
};

TEST(CalibrationObservability, CovarianceEqualsCeresCovarianceWithRobustLossesAndNuisances) {
  sensors::Calibration c;
  c.q_I_L = geometry::Exp(Eigen::Vector3d(0.2, -0.1, 0.4));
  c.p_I_L = Eigen::Vector3d(0.5, -0.2, 0.1);
  std::vector<EstimatedBlock> blocks = {
      BlockOf(sensors::CalibrationBlockId::kLidarRotation, &c),
      BlockOf(sensors::CalibrationBlockId::kLidarTranslation, &c)};
  blocks[0].prior = c.q_I_L.coeffs();
  blocks[0].prior_sigma = Eigen::Vector3d::Constant(0.1);
  blocks[1].prior = c.p_I_L;
  blocks[1].prior_sigma = Eigen::Vector3d::Constant(0.3);
  geometry::RightQuaternionManifold manifold;
  ceres::Problem::Options options;
  options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(options);
  problem.AddParameterBlock(c.q_I_L.coeffs().data(), 4, &manifold);
  std::vector<double> states(6, 0.05);
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 0.5);
  for (int k = 0; k < 30; ++k) {
    RotatedPointRow row{Eigen::Vector3d(noise(rng), noise(rng), 1.0 + noise(rng)),
                        Eigen::Vector3d(noise(rng), noise(rng), noise(rng))};
    problem.AddResidualBlock(
        new ceres::AutoDiffCostFunction<RotatedPointRow, 3, 4, 3, 1>(new RotatedPointRow(row)),
        new ceres::HuberLoss(1.0), c.q_I_L.coeffs().data(), c.p_I_L.data(),
        &states[static_cast<size_t>(k % 6)]);
  }
  AddBlockPriors(blocks, factors::LossOptions(), &problem);
  const BlockCovariance covariance = ComputeBlockCovariance(blocks, &problem);
  ASSERT_TRUE(covariance.ok);

  ceres::Covariance::Options ceres_options;
  ceres_options.algorithm_type = ceres::DENSE_SVD;
  ceres::Covariance reference(ceres_options);
  const std::vector<const double*> parameters = {c.q_I_L.coeffs().data(), c.p_I_L.data()};
  ASSERT_TRUE(reference.Compute(parameters, &problem));
  Eigen::Matrix<double, 6, 6, Eigen::RowMajor> expected;
  ASSERT_TRUE(reference.GetCovarianceMatrixInTangentSpace(parameters, expected.data()));
  EXPECT_TRUE(covariance.matrix.isApprox(expected, 1e-9)) << covariance.matrix << "\n\n"
                                                          << expected;

  // J and J^T J formed on two threads (the columns split between them) give the same bits.
  const BlockCovariance two_threads = ComputeBlockCovariance(blocks, &problem, 2);
  ASSERT_TRUE(two_threads.ok);
  EXPECT_TRUE((two_threads.matrix.array() == covariance.matrix.array()).all())
      << two_threads.matrix - covariance.matrix;
}

// The error budget of a linear problem at its truth: the shares sum to truth - estimate of
// the solve, each share is H^-1 J_s^T r_s and each spread the diagonal of
// (H^-1 J_s^T J_s H^-1)^(1/2), and the spreads' squares sum to the covariance.
TEST(CalibrationObservability, ErrorBudgetSplitsTheErrorOfALinearSolveBySource) {
  const Eigen::Vector3d truth(0.30, -0.05, 0.55);
  const double true_s = 1.8;
  Eigen::Vector3d p = truth;
  double s = true_s;
  std::vector<EstimatedBlock> blocks = {
      VectorBlock(p.data(), Eigen::Vector3d(0.28, -0.04, 0.50), 0.3, 0.05)};
  ceres::Problem problem;
  std::vector<ResidualSource> sources = {{"first", {}}, {"second", {}}, {"priors", {}}};
  const auto row = [&](const LinearRow& r, int source) {
    sources[static_cast<size_t>(source)].residual_blocks.push_back(problem.AddResidualBlock(
        new ceres::AutoDiffCostFunction<LinearRow, 1, 3, 1>(new LinearRow(r)), nullptr, p.data(),
        &s));
  };
  // Measurements of the truth with noise of a few sigma (sigma = 1 / weight).
  row({100.0, 1.0, 0.0, 0.5, 0.0, 0.30 + 0.275 + 0.013}, 0);  // x + z/2
  row({50.0, 0.0, 1.0, 0.0, 0.0, -0.05 - 0.01}, 0);           // y
  row({100.0, -1.0, 0.0, 0.0, 1.0, 1.5 - 0.02}, 1);           // s - x
  row({20.0, 0.0, 0.0, 1.0, 1.0, 0.55 + 1.8 + 0.04}, 1);      // z + s
  AddBlockPriors(blocks, factors::LossOptions(), &problem);
  std::vector<ceres::ResidualBlockId> all;
  problem.GetResidualBlocks(&all);
  sources[2].residual_blocks.assign(all.begin() + 4, all.end());

  const ErrorBudget budget = ComputeErrorBudget(blocks, &problem, sources);
  ASSERT_TRUE(budget.ok);
  EXPECT_THAT(budget.sources, ::testing::ElementsAre("first", "second", "priors"));
  const BlockCovariance covariance = ComputeBlockCovariance(blocks, &problem);
  EXPECT_TRUE(
      budget.spread.cwiseAbs2().rowwise().sum().isApprox(covariance.matrix.diagonal(), 1e-12));
  // Each share by hand: J and r of the source, H^-1 over (p, s).
  ceres::Problem::EvaluateOptions evaluate;
  evaluate.parameter_blocks = {p.data(), &s};
  ceres::CRSMatrix crs;
  std::vector<double> r;
  problem.Evaluate(evaluate, nullptr, &r, nullptr, &crs);
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(crs.num_rows, crs.num_cols);
  for (int i = 0; i < crs.num_rows; ++i) {
    for (int k = crs.rows[i]; k < crs.rows[i + 1]; ++k) J(i, crs.cols[k]) = crs.values[k];
  }
  const Eigen::MatrixXd H_inverse = (J.transpose() * J).inverse();
  const Eigen::Map<const Eigen::VectorXd> residuals(r.data(), static_cast<Eigen::Index>(r.size()));
  const std::vector<std::pair<int, int>> rows_of = {{0, 2}, {2, 2}, {4, 3}};  // rows per source
  for (int k = 0; k < 3; ++k) {
    const auto [first, n] = rows_of[static_cast<size_t>(k)];
    const Eigen::VectorXd share =
        H_inverse.topRows(3) * J.middleRows(first, n).transpose() * residuals.segment(first, n);
    EXPECT_TRUE(budget.share.col(k).isApprox(share, 1e-12)) << k;
    const Eigen::MatrixXd sensitivity = J.middleRows(first, n) * H_inverse.leftCols(3);
    const Eigen::VectorXd spread = sensitivity.cwiseAbs2().colwise().sum().cwiseSqrt();
    EXPECT_TRUE(budget.spread.col(k).isApprox(spread, 1e-12)) << k;
  }
  // Linear: the solve lands where the step says, so the shares sum to truth - estimate.
  ceres::Solver::Options options;
  options.function_tolerance = options.gradient_tolerance = options.parameter_tolerance = 1e-15;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  EXPECT_TRUE(budget.share.rowwise().sum().isApprox(truth - p, 1e-9))
      << budget.share.rowwise().sum().transpose() << " vs " << (truth - p).transpose();
  EXPECT_GT((truth - p).norm(), 1e-3);  // there is an error to split
}

// Eq. C7 on a linear problem: p held fixed, s solved. Its x is 7 sigma off the rows' value,
// y is where the rows put it, z is 10 prior sigmas off rows that know it only as well as the
// prior: only x is named, its step the Gauss-Newton step of (p, s) under p's prior at the fixed
// value (the rows' value shrunk by the prior), and the problem is as it was afterwards.
TEST(CalibrationObservability, NamesTheFixedDirectionsTheDataWouldMove) {
  Eigen::Vector3d p(0.30 + 0.1, -0.05, 0.55 + 3.0);
  double s = 0.0;
  std::vector<EstimatedBlock> fixed = {VectorBlock(p.data(), p, 0.3, 0.05)};
  ceres::Problem problem;
  const auto row = [&](const LinearRow& r) {
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<LinearRow, 1, 3, 1>(new LinearRow(r)),
                             nullptr, p.data(), &s);
  };
  row({100.0, 1.0, 0.0, 0.0, -1.0, 0.30 - 1.5});  // x - s
  row({100.0, 0.0, 0.0, 0.0, 1.0, 1.5});          // s
  row({100.0, 0.0, 1.0, 0.0, 0.0, -0.05});        // y
  row({1.0 / 0.3, 0.0, 0.0, 1.0, 0.0, 0.55});     // z, as well as the prior knows it
  problem.SetParameterBlockConstant(p.data());
  ceres::Solver::Options options;
  options.function_tolerance = options.gradient_tolerance = options.parameter_tolerance = 1e-15;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  const double solved_s = s;
  // The step by hand: J over (p, s) at the solution, p's prior information added.
  ceres::Problem::EvaluateOptions evaluate;
  evaluate.parameter_blocks = {p.data(), &s};
  problem.SetParameterBlockVariable(p.data());
  ceres::CRSMatrix crs;
  std::vector<double> r;
  problem.Evaluate(evaluate, nullptr, &r, nullptr, &crs);
  problem.SetParameterBlockConstant(p.data());
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(crs.num_rows, crs.num_cols);
  for (int i = 0; i < crs.num_rows; ++i) {
    for (int k = crs.rows[i]; k < crs.rows[i + 1]; ++k) J(i, crs.cols[k]) = crs.values[k];
  }
  Eigen::MatrixXd H = J.transpose() * J;
  H.topLeftCorner(3, 3).diagonal().array() += 1.0 / (0.3 * 0.3);
  const Eigen::MatrixXd H_inverse = H.inverse();
  const Eigen::VectorXd step =
      -H_inverse * J.transpose() *
      Eigen::Map<const Eigen::VectorXd>(r.data(), static_cast<Eigen::Index>(r.size()));

  const std::vector<FixedDirectionMove> moved = FixedDirectionsTheDataMove(fixed, &problem, 1, 5.0);
  ASSERT_EQ(moved.size(), 1u);
  EXPECT_EQ(moved[0].block, 0u);
  EXPECT_EQ(moved[0].direction, 0);
  EXPECT_NEAR(moved[0].step, step(0), 1e-12);
  EXPECT_NEAR(moved[0].step, -0.1, 1e-3);  // 7 sigma
  EXPECT_NEAR(moved[0].sigma, std::sqrt(H_inverse(0, 0)), 1e-12);
  EXPECT_THAT(
      moved[0].text,
      ::testing::StartsWith("x is fixed, but the data would move it by -9.98 cm (sigma 1.41 cm"));
  // z's step is 7 of its sigmas too, but its sigma is above half the prior's: the data do
  // not inform it as an estimate would keep it (Informed), so it is not judged.
  EXPECT_NEAR(step(2), -1.5, 1e-9);
  EXPECT_GT(std::abs(step(2)), 5.0 * std::sqrt(H_inverse(2, 2)));
  EXPECT_GT(std::sqrt(H_inverse(2, 2)), 0.5 * 0.3);
  // As it was: p constant and unchanged, s at its solution, no prior left behind.
  EXPECT_TRUE(problem.IsParameterBlockConstant(p.data()));
  EXPECT_EQ(p, Eigen::Vector3d(0.40, -0.05, 3.55));
  EXPECT_EQ(s, solved_s);
  EXPECT_EQ(problem.NumResidualBlocks(), 4);
  // A block stated exact (a sigma of zero) is not judged, and the problem stays as it was.
  std::vector<EstimatedBlock> exact = fixed;
  exact[0].prior_sigma.setZero();
  EXPECT_THAT(FixedDirectionsTheDataMove(exact, &problem, 1, 5.0), ::testing::IsEmpty());
  EXPECT_TRUE(problem.IsParameterBlockConstant(p.data()));
  EXPECT_EQ(problem.NumResidualBlocks(), 4);
  // At the rows' values nothing is named; a block the problem does not hold is not judged.
  p = Eigen::Vector3d(0.30, -0.05, 0.55);
  ceres::Solve(options, &problem, &summary);
  EXPECT_THAT(FixedDirectionsTheDataMove(fixed, &problem, 1, 5.0), ::testing::IsEmpty());
  double elsewhere = 0.0;
  std::vector<EstimatedBlock> absent = {
      VectorBlock(&elsewhere, Eigen::Vector3d::Zero(), 0.3, 0.05)};
  absent[0].size = 1;
  absent[0].prior = Eigen::VectorXd::Zero(1);
  EXPECT_THAT(FixedDirectionsTheDataMove(absent, &problem, 1, 5.0), ::testing::IsEmpty());
}

// A block p (with its prior) and a free s, measured by linear rows of (p, s).
struct LinearRowsProblem {
  Eigen::Vector3d p{0.30, -0.05, 0.55};
  double s = 1.8;
  std::vector<EstimatedBlock> blocks;
  ceres::Problem problem;
  std::vector<ceres::ResidualBlockId> ids;  // the rows', in order

  explicit LinearRowsProblem(const std::vector<LinearRow>& rows)
      : blocks({VectorBlock(p.data(), Eigen::Vector3d(0.28, -0.04, 0.50), 0.3, 0.05)}) {
    for (const LinearRow& r : rows) {
      ids.push_back(problem.AddResidualBlock(
          new ceres::AutoDiffCostFunction<LinearRow, 1, 3, 1>(new LinearRow(r)), nullptr, p.data(),
          &s));
    }
    AddBlockPriors(blocks, factors::LossOptions(), &problem);
  }
};

// The budget's scaled covariance is ComputeBlockCovariance's with the same scaled blocks, from
// the one J the budget evaluates; without a scale it is the budget's own covariance.
TEST(CalibrationObservability, ErrorBudgetGivesTheScaledCovarianceFromItsJacobian) {
  LinearRowsProblem rows({{100.0, 1.0, 0.0, 0.5, 0.0, 0.6},
                          {50.0, 0.0, 1.0, 0.0, 0.0, -0.06},
                          {100.0, -1.0, 0.0, 0.0, 1.0, 1.48},
                          {20.0, 0.0, 0.0, 1.0, 1.0, 2.39}});
  const std::vector<EstimatedBlock>& blocks = rows.blocks;
  ceres::Problem& problem = rows.problem;
  const std::vector<ceres::ResidualBlockId>& ids = rows.ids;
  const ScaledInformation scaled{{ids[0], ids[3]}, 0.25};
  const ErrorBudget budget = ComputeErrorBudget(blocks, &problem, {{"all", ids}}, 1, scaled);
  ASSERT_TRUE(budget.ok);
  ASSERT_TRUE(budget.scaled_covariance.ok);
  const BlockCovariance expected = ComputeBlockCovariance(blocks, &problem, 1, {}, scaled);
  EXPECT_TRUE(budget.scaled_covariance.matrix.isApprox(expected.matrix, 1e-14))
      << budget.scaled_covariance.matrix - expected.matrix;
  EXPECT_EQ(budget.scaled_covariance.offsets, expected.offsets);
  // The scale matters: a quarter of two rows' information widens the covariance.
  EXPECT_GT(budget.scaled_covariance.matrix(0, 0), 1.01 * budget.covariance.matrix(0, 0));
  const ErrorBudget unscaled = ComputeErrorBudget(blocks, &problem, {{"all", ids}}, 1,
                                                  ScaledInformation{{ids[0], ids[3]}, 1.0});
  EXPECT_TRUE(
      (unscaled.scaled_covariance.matrix.array() == unscaled.covariance.matrix.array()).all());
}

// A shared fill-reducing ordering is computed by the first call and reused by the next, with the
// same bits as each call's own.
TEST(CalibrationObservability, ASharedOrderingGivesTheSameCovariance) {
  LinearRowsProblem rows({{100.0, 1.0, 0.0, 0.5, 0.0, 0.6},
                          {20.0, 0.0, 0.0, 1.0, 1.0, 2.39},
                          {10.0, 0.0, 1.0, 0.0, 1.0, 1.7}});
  const std::vector<EstimatedBlock>& blocks = rows.blocks;
  ceres::Problem& problem = rows.problem;
  const std::vector<ceres::ResidualBlockId>& ids = rows.ids;
  CovarianceOrdering ordering;
  const BlockCovariance first = ComputeBlockCovariance(blocks, &problem, 1, {}, {}, &ordering);
  EXPECT_EQ(ordering.P.size(), 4);  // the tangent columns of p and s
  const ScaledInformation scaled{{ids[0]}, 0.5};
  const ErrorBudget budget =
      ComputeErrorBudget(blocks, &problem, {{"rows", ids}}, 1, scaled, &ordering);
  const ErrorBudget own = ComputeErrorBudget(blocks, &problem, {{"rows", ids}}, 1, scaled);
  ASSERT_TRUE(first.ok && budget.ok && own.ok);
  const BlockCovariance alone = ComputeBlockCovariance(blocks, &problem);
  EXPECT_TRUE((first.matrix.array() == alone.matrix.array()).all());
  EXPECT_TRUE((budget.covariance.matrix.array() == own.covariance.matrix.array()).all());
  EXPECT_TRUE(
      (budget.scaled_covariance.matrix.array() == own.scaled_covariance.matrix.array()).all());
  EXPECT_TRUE((budget.share.array() == own.share.array()).all());
}

// Eq. C6: the information of the scaled residual blocks is multiplied by the scale, the rest
// unchanged: (J_1^T J_1 + s J_2^T J_2)^-1 by hand.
TEST(CalibrationObservability, ScaledInformationMultipliesTheGivenBlocksInformation) {
  Eigen::Vector3d p(0.3, -0.05, 0.55);
  double s = 1.8;
  std::vector<EstimatedBlock> blocks = {VectorBlock(p.data(), p, 0.3, 0.05)};
  ceres::Problem problem;
  std::vector<ceres::ResidualBlockId> scaled_ids;
  const auto row = [&](const LinearRow& r, bool scaled) {
    const ceres::ResidualBlockId id = problem.AddResidualBlock(
        new ceres::AutoDiffCostFunction<LinearRow, 1, 3, 1>(new LinearRow(r)), nullptr, p.data(),
        &s);
    if (scaled) scaled_ids.push_back(id);
  };
  row({100.0, 1.0, 0.0, 0.5, 0.0, 0.6}, false);
  row({50.0, 0.0, 1.0, 0.0, 0.0, -0.06}, true);
  row({100.0, -1.0, 0.0, 0.0, 1.0, 1.5}, true);
  row({20.0, 0.0, 0.0, 1.0, 1.0, 2.4}, false);
  row({30.0, 1.0, 1.0, 0.0, 0.0, 0.2}, false);
  ceres::Problem::EvaluateOptions evaluate;
  evaluate.parameter_blocks = {p.data(), &s};
  ceres::CRSMatrix crs;
  problem.Evaluate(evaluate, nullptr, nullptr, nullptr, &crs);
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(crs.num_rows, crs.num_cols);
  for (int i = 0; i < crs.num_rows; ++i) {
    for (int k = crs.rows[i]; k < crs.rows[i + 1]; ++k) J(i, crs.cols[k]) = crs.values[k];
  }
  const double scale = 1.0 / 0.6;
  Eigen::VectorXd weight = Eigen::VectorXd::Ones(5);
  weight(1) = weight(2) = scale;
  const Eigen::MatrixXd expected = (J.transpose() * weight.asDiagonal() * J).inverse();
  const BlockCovariance covariance =
      ComputeBlockCovariance(blocks, &problem, 1, {}, ScaledInformation{scaled_ids, scale});
  ASSERT_TRUE(covariance.ok);
  EXPECT_TRUE(covariance.matrix.isApprox(expected.topLeftCorner(3, 3), 1e-12))
      << covariance.matrix << "\nvs\n"
      << expected.topLeftCorner(3, 3);
  const BlockCovariance plain = ComputeBlockCovariance(blocks, &problem);
  EXPECT_TRUE(plain.matrix.isApprox((J.transpose() * J).inverse().topLeftCorner(3, 3), 1e-12));
}

TEST(CalibrationObservability, CovarianceOfASingularProblemIsRefusedAndConstantBlocksAreZero) {
  Eigen::Vector3d p(0.1, 0.2, 0.3);
  Eigen::Vector3d held(1.0, 2.0, 3.0);
  std::vector<EstimatedBlock> blocks = {VectorBlock(p.data(), p, 0.3, 0.05),
                                        VectorBlock(held.data(), held, 0.3, 0.05)};
  ceres::Problem problem;
  AddBlockPriors(blocks, factors::LossOptions(), &problem);
  problem.SetParameterBlockConstant(held.data());
  BlockCovariance covariance = ComputeBlockCovariance(blocks, &problem);
  ASSERT_TRUE(covariance.ok);
  const Eigen::Matrix3d variance_p = covariance.matrix.topLeftCorner(3, 3);
  EXPECT_TRUE(variance_p.isApprox(Eigen::Matrix3d::Identity() * 0.09)) << variance_p;
  EXPECT_TRUE(covariance.matrix.rightCols(3).isZero());
  EXPECT_TRUE(covariance.matrix.bottomRows(3).isZero());

  // A state that enters a residual without moving it: J^T J is singular and no covariance
  // is claimed.
  double lone = 0.0;
  problem.AddResidualBlock(new ceres::AutoDiffCostFunction<LinearRow, 1, 3, 1>(
                               new LinearRow{1.0, 1.0, 0.0, 0.0, 0.0, 0.0}),
                           nullptr, p.data(), &lone);
  covariance = ComputeBlockCovariance(blocks, &problem);
  EXPECT_FALSE(covariance.ok);
}

// A drive in miniature for Eq. C8: a calibration p and one state x_k per keyframe, each
// keyframe with a row that sees both, w (x_k + a_k . p - m), and one that sees its state
// alone, w (x_k - m). The regressor a_k has a constant part, so an error that stays on for many
// keyframes moves p as a whole. The rows' noise is N(0, 1/w^2), white or, with `correlation`,
// the first rows' an AR(1) sequence of that variance, under `loss`; the problem is solved to
// its minimum.
struct KeyframeRowsProblem {
  static constexpr int kKeyframes = 240;
  Eigen::Vector3d p{0.30, -0.05, 0.55};
  std::vector<double> x = std::vector<double>(kKeyframes, 0.0);
  std::vector<EstimatedBlock> blocks;
  ceres::Problem problem;
  ResidualSource rows{"rows", {}};

  KeyframeRowsProblem(uint32_t seed, double correlation,
                      const Eigen::Vector3d& prior_offset = Eigen::Vector3d::Zero(),
                      double prior_sigma = 1.0, const factors::LossOptions& loss = {},
                      int state_rows = 1)
      : blocks({VectorBlock(p.data(), p + prior_offset, prior_sigma, 0.05)}) {
    const double weight = 20.0;
    ceres::LossFunction* rho = factors::MakeLossFunction(loss);  // the problem deletes it once
    const Eigen::Vector3d truth = p;
    std::mt19937 random(seed);
    std::normal_distribution<double> normal;
    double drift = normal(random);
    for (int k = 0; k < kKeyframes; ++k) {
      const double phase = 6.0 * M_PI * k / kKeyframes;
      const Eigen::Vector3d a(1.0, std::sin(phase), std::cos(phase) + 0.3 * normal(random));
      const double state = 0.1 * k;
      drift = correlation * drift + std::sqrt(1.0 - correlation * correlation) * normal(random);
      rows.residual_blocks.push_back(problem.AddResidualBlock(
          new ceres::AutoDiffCostFunction<LinearRow, 1, 3, 1>(new LinearRow{
              weight, a.x(), a.y(), a.z(), 1.0, state + a.dot(truth) + drift / weight}),
          rho, p.data(), &x[static_cast<size_t>(k)]));
      for (int row = 0; row < state_rows; ++row) {
        rows.residual_blocks.push_back(problem.AddResidualBlock(
            new ceres::AutoDiffCostFunction<LinearRow, 1, 3, 1>(
                new LinearRow{weight, 0.0, 0.0, 0.0, 1.0, state + normal(random) / weight}),
            rho, p.data(), &x[static_cast<size_t>(k)]));
      }
    }
    AddBlockPriors(blocks, factors::LossOptions(), &problem);
    ceres::Solver::Options options;
    options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
    options.function_tolerance = options.gradient_tolerance = options.parameter_tolerance = 1e-15;
    ceres::Solver::Summary summary;
    ceres::Solve(options, &problem, &summary);
  }
};

// Eq. C8's expectation is exact for a linear problem with white noise at its stated sigma: over
// many drives the stretches' scatter averages to it, about half the share the noise model gives,
// because each keyframe's state takes up part of its rows' noise. The model part is the error
// budget's spread.
TEST(CalibrationObservability, StretchScatterOfWhiteNoiseAveragesToItsExpectation) {
  constexpr int kDrives = 200;
  Eigen::Vector3d observed_to_expected = Eigen::Vector3d::Zero();
  Eigen::Vector3d observed_to_model = Eigen::Vector3d::Zero();
  Eigen::Vector3d expected_to_model = Eigen::Vector3d::Zero();
  for (uint32_t seed = 1; seed <= kDrives; ++seed) {
    KeyframeRowsProblem drive(seed, 0.0);
    const StretchScatter scatter =
        ComputeStretchScatter(drive.blocks, &drive.problem, {drive.rows}, 8);
    ASSERT_TRUE(scatter.ok);
    ASSERT_EQ(scatter.sources.size(), 1u);
    const StretchScatter::Source& rows = scatter.sources[0];
    observed_to_expected += rows.observed.diagonal().cwiseQuotient(rows.expected.diagonal());
    observed_to_model += rows.observed.diagonal().cwiseQuotient(rows.model.diagonal());
    expected_to_model += rows.expected.diagonal().cwiseQuotient(rows.model.diagonal());
    if (seed == 1) {
      const ErrorBudget budget = ComputeErrorBudget(drive.blocks, &drive.problem, {drive.rows});
      EXPECT_TRUE(rows.model.diagonal().isApprox(budget.spread.col(0).cwiseAbs2(), 1e-9));
      EXPECT_EQ(scatter.stretches, 8);
      EXPECT_THAT(scatter.offsets, ::testing::ElementsAre(0));
    }
  }
  observed_to_expected /= kDrives;
  observed_to_model /= kDrives;
  expected_to_model /= kDrives;
  // Each drive's ratio scatters about as chi-square(7) / 7 (8 stretches less their mean): the
  // mean of 200 within 0.1, 2.6 of its sigmas (measured 0.97-0.99).
  // Against the model's share the scatter falls short by the part the states take up.
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(observed_to_expected(i), 1.0, 0.1) << i;
    EXPECT_NEAR(observed_to_model(i), expected_to_model(i), 0.1) << i;
    EXPECT_LT(expected_to_model(i), 0.85) << i;
  }
}

// The scatter's degrees of freedom per coordinate are Satterthwaite's for the stretches'
// expected shares less their mean, (sum_b E_b)^2 / sum_b E_b^2 - 1: 7 for 8 equal stretches.
// This drive's regressors turn three times over 240 keyframes, so its 8 stretches inform p about
// equally: between 6 and 7. With the rows that see p in one stretch alone, 1.
TEST(CalibrationObservability, StretchScatterCountsTheStretchesThatInform) {
  KeyframeRowsProblem drive(1, 0.0);
  const StretchScatter scatter =
      ComputeStretchScatter(drive.blocks, &drive.problem, {drive.rows}, 8);
  ASSERT_TRUE(scatter.ok);
  const Eigen::VectorXd& dof = scatter.sources[0].degrees_of_freedom;
  ASSERT_EQ(dof.size(), 3);
  for (int i = 0; i < 3; ++i) {
    EXPECT_GT(dof(i), 6.0) << i;
    EXPECT_LE(dof(i), 7.0) << i;
  }
  // The same rows with the first stretch's alone seeing p: a stretch is 1/8 of the rows.
  Eigen::Vector3d p(0.30, -0.05, 0.55);
  std::vector<double> x(KeyframeRowsProblem::kKeyframes, 0.0);
  ceres::Problem problem;
  ResidualSource rows{"rows", {}};
  std::mt19937 random(1);
  std::normal_distribution<double> normal;
  for (int k = 0; k < KeyframeRowsProblem::kKeyframes; ++k) {
    const double phase = 6.0 * M_PI * k / KeyframeRowsProblem::kKeyframes;
    const Eigen::Vector3d a = k < KeyframeRowsProblem::kKeyframes / 8
                                  ? Eigen::Vector3d(1.0, std::sin(phase), std::cos(phase))
                                  : Eigen::Vector3d::Zero();
    for (const double seen : {1.0, 0.0}) {
      rows.residual_blocks.push_back(problem.AddResidualBlock(
          new ceres::AutoDiffCostFunction<LinearRow, 1, 3, 1>(
              new LinearRow{20.0, seen * a.x(), seen * a.y(), seen * a.z(), 1.0,
                            0.1 * k + seen * a.dot(p) + normal(random) / 20.0}),
          nullptr, p.data(), &x[static_cast<size_t>(k)]));
    }
  }
  const std::vector<EstimatedBlock> blocks = {VectorBlock(p.data(), p, 1.0, 0.05)};
  AddBlockPriors(blocks, factors::LossOptions(), &problem);
  ceres::Solver::Options options;
  options.function_tolerance = options.gradient_tolerance = options.parameter_tolerance = 1e-15;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  const StretchScatter one = ComputeStretchScatter(blocks, &problem, {rows}, 8);
  ASSERT_TRUE(one.ok);
  for (int i = 0; i < 3; ++i) EXPECT_DOUBLE_EQ(one.sources[0].degrees_of_freedom(i), 1.0) << i;
}

// Under a robust loss the rows' shares scatter as the M-estimator weighs them: for Gaussian rows
// under Huber at 1 sigma, 0.57 of what their Jacobians state (factors::ExpectedRowPull). With
// that share ratio the expectation holds again; without it, errors correlated over the log
// up to 1.75 times their stated variance would read as white. Each keyframe's state has 16
// rows of its own here, as a drive's states have the other sensors: with one, the fit takes
// half of each row's noise and the loss sees residuals that much smaller (measured 0.75
// without the ratio; 4 rows: 0.60; 16: 0.56-0.59).
TEST(CalibrationObservability, StretchScatterUnderARobustLossAveragesToItsExpectation) {
  constexpr int kDrives = 200;
  const factors::LossOptions huber{factors::RobustLoss::kHuber, 1.0};
  const std::unique_ptr<ceres::LossFunction> rho(factors::MakeLossFunction(huber));
  const factors::RowPull pull = factors::ExpectedRowPull(rho.get(), 1);
  Eigen::Vector3d with_ratio = Eigen::Vector3d::Zero();
  for (uint32_t seed = 1; seed <= kDrives; ++seed) {
    KeyframeRowsProblem drive(seed, 0.0, Eigen::Vector3d::Zero(), 1.0, huber, 16);
    drive.rows.share_ratio = pull.pull_squared / pull.weight;
    const StretchScatter scaled =
        ComputeStretchScatter(drive.blocks, &drive.problem, {drive.rows}, 8);
    ASSERT_TRUE(scaled.ok);
    const StretchScatter::Source& b = scaled.sources[0];
    if (seed == 1) {
      drive.rows.share_ratio = 1.0;
      const StretchScatter plain =
          ComputeStretchScatter(drive.blocks, &drive.problem, {drive.rows}, 8);
      ASSERT_TRUE(plain.ok);
      EXPECT_TRUE(
          b.expected.isApprox(plain.sources[0].expected * pull.pull_squared / pull.weight, 1e-12));
    }
    with_ratio += b.observed.diagonal().cwiseQuotient(b.expected.diagonal()) / kDrives;
  }
  const Eigen::Vector3d least_squares = with_ratio * pull.pull_squared / pull.weight;
  // As the white-noise test: the mean of 200 drives' chi-square(7) / 7 within 0.1.
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(with_ratio(i), 1.0, 0.1) << i;
    EXPECT_LT(least_squares(i), 0.7) << i;
  }
}

// Noise correlated over about 20 keyframes moves p far more than white noise would; the
// stretches see it along the regressor's constant part (x).
TEST(CalibrationObservability, StretchScatterFindsErrorsCorrelatedOverTheLog) {
  double correlated = 0.0;
  double white = 0.0;
  for (uint32_t seed = 1; seed <= 10; ++seed) {
    for (const double correlation : {0.95, 0.0}) {
      KeyframeRowsProblem drive(seed, correlation);
      const StretchScatter scatter =
          ComputeStretchScatter(drive.blocks, &drive.problem, {drive.rows}, 8);
      ASSERT_TRUE(scatter.ok);
      const StretchScatter::Source& rows = scatter.sources[0];
      (correlation > 0.0 ? correlated : white) += rows.observed(0, 0) / rows.expected(0, 0) / 10;
    }
  }
  EXPECT_GT(correlated, 4.0);  // 8.8 measured
  EXPECT_NEAR(white, 1.0, 0.5);
}

// A prior that pulls p off the rows' optimum moves every stretch's share alike: the scatter
// about their mean does not see it (without the centring the first coordinate's ratio is
// 11.7 here).
TEST(CalibrationObservability, StretchScatterIgnoresAPullCommonToEveryStretch) {
  double ratio = 0.0;
  for (uint32_t seed = 1; seed <= 10; ++seed) {
    KeyframeRowsProblem drive(seed, 0.0, Eigen::Vector3d(0.05, 0.0, 0.0), 0.002);
    ASSERT_GT(std::abs(drive.p.x() - 0.30), 0.02);  // pulled towards the prior
    const StretchScatter scatter =
        ComputeStretchScatter(drive.blocks, &drive.problem, {drive.rows}, 8);
    ASSERT_TRUE(scatter.ok);
    ratio += scatter.sources[0].observed(0, 0) / scatter.sources[0].expected(0, 0) / 10;
  }
  EXPECT_NEAR(ratio, 1.0, 0.5);
}

// Off the minimum (here: every variable moved), the scatter at the Gauss-Newton step's
// residuals is the scatter at the minimum: exactly, for this linear problem. At the values as
// they are, the offset's pull differs from stretch to stretch and reads as scatter (here the
// first coordinate's: 3.0 times the minimum's).
TEST(CalibrationObservability, StretchScatterAtTheGaussNewtonStepIsTheMinimumsScatter) {
  KeyframeRowsProblem drive(3, 0.0);
  const StretchScatter at_minimum =
      ComputeStretchScatter(drive.blocks, &drive.problem, {drive.rows}, 8);
  drive.p += Eigen::Vector3d(0.01, -0.02, 0.03);
  for (size_t k = 0; k < drive.x.size(); ++k) drive.x[k] += 0.05 * std::sin(0.1 * k);
  const StretchScatter at_step =
      ComputeStretchScatter(drive.blocks, &drive.problem, {drive.rows}, 8, 1, nullptr, true);
  const StretchScatter as_is = ComputeStretchScatter(drive.blocks, &drive.problem, {drive.rows}, 8);
  ASSERT_TRUE(at_minimum.ok && at_step.ok && as_is.ok);
  const StretchScatter::Source& minimum = at_minimum.sources[0];
  const StretchScatter::Source& step = at_step.sources[0];
  EXPECT_TRUE(step.observed.isApprox(minimum.observed, 1e-6)) << step.observed << "\n"
                                                              << minimum.observed;
  EXPECT_TRUE(step.expected.isApprox(minimum.expected, 1e-9));
  EXPECT_GT(as_is.sources[0].observed(0, 0), 2.0 * minimum.observed(0, 0));
}

// The step's gradient sums the residual blocks in one order whatever the thread count, so the
// scatter at the step is the same to the bit on 1 and 4 threads, run after run. (Summed by
// Ceres' threads, the blocks fall to them as the scheduling goes, and the last bits moved.)
TEST(CalibrationObservability, StretchScatterAtTheStepDoesNotDependOnTheThreads) {
  KeyframeRowsProblem drive(3, 0.0, Eigen::Vector3d::Zero(), 1.0, {}, 8);
  for (size_t k = 0; k < drive.x.size(); ++k) drive.x[k] += 0.05 * std::sin(0.1 * k);
  const auto at_step = [&](int threads) {
    return ComputeStretchScatter(drive.blocks, &drive.problem, {drive.rows}, 8, threads, nullptr,
                                 true);
  };
  const StretchScatter one = at_step(1);
  ASSERT_TRUE(one.ok);
  for (int run = 0; run < 20; ++run) {
    const StretchScatter four = at_step(4);
    ASSERT_TRUE(four.ok);
    ASSERT_EQ(four.sources[0].observed, one.sources[0].observed) << "run " << run;
  }
}

TEST(CalibrationObservability, StretchScatterLeavesOutShortSourcesAndRefusesOneStretch) {
  KeyframeRowsProblem drive(1, 0.0);
  ResidualSource few{"few",
                     {drive.rows.residual_blocks.begin(), drive.rows.residual_blocks.begin() + 5}};
  const StretchScatter scatter =
      ComputeStretchScatter(drive.blocks, &drive.problem, {few, drive.rows}, 8);
  ASSERT_TRUE(scatter.ok);
  ASSERT_EQ(scatter.sources.size(), 1u);
  EXPECT_EQ(scatter.sources[0].name, "rows");
  EXPECT_THROW(ComputeStretchScatter(drive.blocks, &drive.problem, {drive.rows}, 1), Error);
}

}  // namespace
}  // namespace estimation
}  // namespace autocal
