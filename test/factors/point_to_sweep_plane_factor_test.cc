#include "autocal/factors/point_to_sweep_plane_factor.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <limits>
#include <memory>
#include <random>
#include <vector>

#include "analytic_motion.h"
#include "autocal/common/error.h"
#include "autocal/factors/point_to_sweep_plane_group_factor.h"
#include "autocal/geometry/manifolds.h"
#include "autocal/geometry/so3.h"
#include "factor_test_utils.h"
#include "factors/point_group_storage.h"

namespace autocal {
namespace factors {
namespace {

using geometry::Exp;
using test::AnalyticTrajectory;
using test::kGravity;
using test::TrueMotion;

// Keyframe states k and j, extrinsic and offset as parameter blocks.
struct State {
  Eigen::Quaterniond q_k, q_j, q_I_L;
  Eigen::Vector3d p_k, v_k, p_j, v_j, p_I_L;
  double offset_s = 0.0;
  std::vector<double*> Blocks() {
    return {q_k.coeffs().data(),   p_k.data(),   v_k.data(),
            q_j.coeffs().data(),   p_j.data(),   v_j.data(),
            q_I_L.coeffs().data(), p_I_L.data(), &offset_s};
  }
};

std::vector<const ceres::Manifold*> Manifolds(const ceres::Manifold* q) {
  return {q, nullptr, nullptr, q, nullptr, nullptr, q, nullptr, nullptr};
}

// A true scene: keyframes at t_k and t_j on the analytic trajectory, sweep j's LiDAR frame at
// its reference instant, a world plane through a point that sweep k measured at tau.
struct Scene {
  AnalyticTrajectory traj;
  State truth;
  double t_k = 2.0, t_j = 3.3;
  double sweep_k_lidar = 1.97, sweep_j_lidar = 3.27;  // LiDAR clock
  Eigen::Vector3d p_L;
  geometry::Plane plane_L;  // in sweep j's LiDAR frame
  double tau;

  Scene(std::mt19937* rng, double tau_s) : tau(tau_s) {
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    truth.q_k = traj.Rotation(t_k);
    truth.p_k = traj.Position(t_k);
    truth.v_k = traj.Velocity(t_k);
    truth.q_j = traj.Rotation(t_j);
    truth.p_j = traj.Position(t_j);
    truth.v_j = traj.Velocity(t_j);
    truth.q_I_L = Exp(Eigen::Vector3d(0.05, -0.03, 1.2));
    truth.p_I_L = Eigen::Vector3d(0.4, -0.1, 0.3);
    truth.offset_s = 0.04;  // t_imu = t_lidar + 0.04 s
    p_L = Eigen::Vector3d(8.0 * u(*rng), 8.0 * u(*rng), 2.0 * u(*rng));
    const double t_point = sweep_k_lidar + tau + truth.offset_s;
    const Eigen::Vector3d p_W =
        traj.Rotation(t_point) * (truth.q_I_L * p_L + truth.p_I_L) + traj.Position(t_point);
    // Sweep j's LiDAR frame at its reference instant.
    const double t_ref = sweep_j_lidar + truth.offset_s;
    const Eigen::Quaterniond q_W_Lj = traj.Rotation(t_ref) * truth.q_I_L;
    const Eigen::Vector3d p_W_Lj = traj.Rotation(t_ref) * truth.p_I_L + traj.Position(t_ref);
    plane_L.normal = Eigen::Vector3d(u(*rng), u(*rng), u(*rng)).normalized();
    plane_L.d = -plane_L.normal.dot(q_W_Lj.conjugate() * (p_W - p_W_Lj));
  }

  PointToSweepPlaneMeasurement Measurement(double offset_linearization_s) const {
    PointToSweepPlaneMeasurement m;
    m.p_L = p_L;
    m.plane_L = plane_L;
    m.sigma_m = 0.03;
    m.offset_linearization_s = offset_linearization_s;
    m.motion = TrueMotion(traj, t_k, sweep_k_lidar + tau + offset_linearization_s - t_k);
    m.plane_motion = TrueMotion(traj, t_j, sweep_j_lidar + offset_linearization_s - t_j);
    return m;
  }
};

double Residual(const ceres::CostFunction& cost, State state) {
  double r = 0.0;
  const std::vector<double*> blocks = state.Blocks();
  EXPECT_TRUE(cost.Evaluate(blocks.data(), &r, nullptr));
  return r;
}

TEST(PointToSweepPlaneFactor, ZeroAtGroundTruth) {
  std::mt19937 rng(1);
  for (double tau : {0.0, 0.031, 0.067, 0.099}) {
    const Scene scene(&rng, tau);
    const PointToSweepPlaneFactor factor(scene.Measurement(scene.truth.offset_s), kGravity);
    EXPECT_NEAR(Residual(factor, scene.truth), 0.0, 1e-10) << "tau = " << tau;
    const std::unique_ptr<ceres::CostFunction> twin(
        CreatePointToSweepPlaneAutoDiff(scene.Measurement(scene.truth.offset_s), kGravity));
    EXPECT_NEAR(Residual(*twin, scene.truth), 0.0, 1e-10) << "tau = " << tau;
  }
}

// A zero, negative or non-finite sigma is refused: it whitened every residual to inf or NaN.
TEST(PointToSweepPlaneFactor, RefusesASigmaThatIsNotPositive) {
  std::mt19937 rng(1);
  const Scene scene(&rng, 0.031);
  for (double sigma_m : {0.0, -0.02, std::numeric_limits<double>::quiet_NaN(),
                         std::numeric_limits<double>::infinity()}) {
    PointToSweepPlaneMeasurement m = scene.Measurement(scene.truth.offset_s);
    m.sigma_m = sigma_m;
    EXPECT_THROW(PointToSweepPlaneFactor(m, kGravity), Error) << sigma_m;
  }
}

// A wrong extrinsic, offset or plane-side state leaves a residual: the plane moves with the
// blocks of the sweep that saw it, it does not absorb their error.
TEST(PointToSweepPlaneFactor, EveryBlockMovesTheResidual) {
  std::mt19937 rng(2);
  const Scene scene(&rng, 0.05);
  const PointToSweepPlaneFactor factor(scene.Measurement(scene.truth.offset_s), kGravity);
  const test::Evaluation at_truth = [&] {
    State s = scene.truth;
    return test::Evaluate(factor, s.Blocks());
  }();
  for (size_t block = 0; block < at_truth.jacobians.size(); ++block) {
    EXPECT_GT(at_truth.jacobians[block].norm(), 1e-3) << "block " << block;
  }
  // Linearized at a wrong offset, evaluated at the true one: first-order exact.
  const double coarse = std::abs(
      Residual(PointToSweepPlaneFactor(scene.Measurement(scene.truth.offset_s - 0.004), kGravity),
               scene.truth));
  const double fine = std::abs(
      Residual(PointToSweepPlaneFactor(scene.Measurement(scene.truth.offset_s - 0.002), kGravity),
               scene.truth));
  EXPECT_GT(coarse, 0.0);
  EXPECT_NEAR(coarse / fine, 4.0, 0.5) << "coarse " << coarse << " fine " << fine;
}

PointMotion RandomMotion(std::mt19937* rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  PointMotion motion;
  motion.dt_s = 0.1 * (u(*rng) + 1.0);
  motion.delta_q = Exp(Eigen::Vector3d(0.3 * u(*rng), 0.3 * u(*rng), 0.3 * u(*rng)));
  motion.delta_v = 2.0 * Eigen::Vector3d(u(*rng), u(*rng), u(*rng));
  motion.delta_p = 2.0 * Eigen::Vector3d(u(*rng), u(*rng), u(*rng));
  motion.omega_rad_s = Eigen::Vector3d(u(*rng), u(*rng), u(*rng));
  return motion;
}

PointToSweepPlaneMeasurement RandomMeasurement(std::mt19937* rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  PointToSweepPlaneMeasurement m;
  m.p_L = 20.0 * Eigen::Vector3d(u(*rng), u(*rng), u(*rng));
  m.motion = RandomMotion(rng);
  m.plane_motion = RandomMotion(rng);
  m.plane_L.normal = Eigen::Vector3d(u(*rng), u(*rng), u(*rng)).normalized();
  m.plane_L.d = 10.0 * u(*rng);
  m.sigma_m = 0.02;
  m.offset_linearization_s = 0.03 * u(*rng);
  return m;
}

// A uniformly random rotation drawn from rng (not from Eigen's global std::rand, which would
// make each test's states depend on the tests run before it).
Eigen::Quaterniond RandomRotation(std::mt19937* rng) {
  std::normal_distribution<double> gauss(0.0, 1.0);
  return Eigen::Quaterniond(Eigen::Vector4d(gauss(*rng), gauss(*rng), gauss(*rng), gauss(*rng)))
      .normalized();
}

State RandomState(std::mt19937* rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  State s;
  s.q_k = RandomRotation(rng);
  s.q_j = RandomRotation(rng);
  s.q_I_L = RandomRotation(rng);
  s.p_k = 50.0 * Eigen::Vector3d(u(*rng), u(*rng), u(*rng));
  s.p_j = 50.0 * Eigen::Vector3d(u(*rng), u(*rng), u(*rng));
  s.v_k = 15.0 * Eigen::Vector3d(u(*rng), u(*rng), u(*rng));
  s.v_j = 15.0 * Eigen::Vector3d(u(*rng), u(*rng), u(*rng));
  s.p_I_L = Eigen::Vector3d(u(*rng), u(*rng), u(*rng));
  s.offset_s = 0.05 * u(*rng);
  return s;
}

TEST(PointToSweepPlaneFactor, JacobiansPassGradientChecker) {
  std::mt19937 rng(3);
  const geometry::RightQuaternionManifold quaternion;
  for (int trial = 0; trial < 50; ++trial) {
    const PointToSweepPlaneFactor factor(RandomMeasurement(&rng), kGravity);
    State state = RandomState(&rng);
    test::ExpectGradientCheckPasses(factor, Manifolds(&quaternion), state.Blocks(), 1e-5,
                                    "trial " + std::to_string(trial));
  }
}

TEST(PointToSweepPlaneFactor, AnalyticMatchesAutodiffTwin) {
  std::mt19937 rng(4);
  const geometry::RightQuaternionManifold quaternion;
  for (int trial = 0; trial < 50; ++trial) {
    const PointToSweepPlaneMeasurement m = RandomMeasurement(&rng);
    const PointToSweepPlaneFactor analytic(m, kGravity);
    const std::unique_ptr<ceres::CostFunction> autodiff(
        CreatePointToSweepPlaneAutoDiff(m, kGravity));
    State state = RandomState(&rng);
    test::ExpectSameJacobians(analytic, *autodiff, Manifolds(&quaternion), state.Blocks(), 1e-9,
                              "trial " + std::to_string(trial));
  }
}

// Blocks asked for without others (a solve holding the calibration fixed asks for no q_I_L,
// p_I_L, offset rows) get the rows they get when every block is asked for.
TEST(PointToSweepPlaneFactor, AnyBlocksAskedForGetTheirFullRows) {
  std::mt19937 rng(8);
  for (int trial = 0; trial < 10; ++trial) {
    const PointToSweepPlaneFactor factor(RandomMeasurement(&rng), kGravity);
    State state = RandomState(&rng);
    const std::vector<double*> values = state.Blocks();
    const test::Evaluation all = test::Evaluate(factor, values);
    for (const std::vector<size_t>& asked :
         {std::vector<size_t>{0, 1, 2, 3, 4, 5}, std::vector<size_t>{6, 7, 8},
          std::vector<size_t>{8}, std::vector<size_t>{}}) {
      std::vector<std::array<double, 4>> rows(9);
      std::vector<double*> jacobians(9, nullptr);
      for (size_t b : asked) jacobians[b] = rows[b].data();
      double residual = 0.0;
      ASSERT_TRUE(factor.Evaluate(values.data(), &residual, jacobians.data()));
      EXPECT_EQ(residual, all.residual(0));
      for (size_t b : asked) {
        for (Eigen::Index c = 0; c < all.jacobians[b].cols(); ++c) {
          EXPECT_EQ(rows[b][static_cast<size_t>(c)], all.jacobians[b](0, c))
              << "trial " << trial << ", block " << b;
        }
      }
    }
  }
}

// ---------------------------------------------------------------------------------------
// Groups (Eq. P9).

std::vector<PointToSweepPlaneMeasurement> RandomGroup(int n, std::mt19937* rng) {
  std::vector<PointToSweepPlaneMeasurement> group;
  for (int i = 0; i < n; ++i) group.push_back(RandomMeasurement(rng));
  return group;
}

TEST(PointToSweepPlaneGroupFactor, WithoutLossItStacksThePointFactors) {
  std::mt19937 rng(5);
  const std::vector<PointToSweepPlaneMeasurement> points = RandomGroup(7, &rng);
  const PointToSweepPlaneGroupFactor group(points, kGravity, LossOptions());
  State state = RandomState(&rng);
  const test::Evaluation stacked = test::Evaluate(group, state.Blocks());
  double distances[7];
  group.WhitenedDistances(state.Blocks().data(), distances);
  for (int i = 0; i < 7; ++i) {
    const PointToSweepPlaneFactor single(points[static_cast<size_t>(i)], kGravity);
    const test::Evaluation one = test::Evaluate(single, state.Blocks());
    EXPECT_EQ(stacked.residual(i), one.residual(0));
    EXPECT_EQ(distances[i], one.residual(0));
    for (size_t b = 0; b < one.jacobians.size(); ++b) {
      EXPECT_EQ(stacked.jacobians[b].row(i), one.jacobians[b].row(0)) << "point " << i;
    }
  }
}

TEST(PointToSweepPlaneGroupFactor, RobustRowsCarryTheRobustCostAndExactJacobians) {
  std::mt19937 rng(6);
  const geometry::RightQuaternionManifold quaternion;
  for (const LossOptions& loss :
       {LossOptions{RobustLoss::kHuber, 1.0}, LossOptions{RobustLoss::kCauchy, 2.0}}) {
    for (int trial = 0; trial < 10; ++trial) {
      std::vector<PointToSweepPlaneMeasurement> points = RandomGroup(5, &rng);
      // Inliers too: a point on its plane within a fraction of a sigma.
      State state = RandomState(&rng);
      for (size_t i = 0; i < 2; ++i) {
        const PointToSweepPlaneFactor single(points[i], kGravity);
        points[i].plane_L.d -= (Residual(single, state) - 0.3) * points[i].sigma_m;
      }
      // No point near Huber's kink (|r| = scale), where the numeric derivatives' steps straddle
      // a jump of the second derivative: such a point is moved half a sigma farther out.
      for (size_t i = 2; i < points.size(); ++i) {
        const PointToSweepPlaneFactor single(points[i], kGravity);
        const double r = Residual(single, state);
        if (loss.type == RobustLoss::kHuber && std::abs(std::abs(r) - loss.scale) < 0.25) {
          points[i].plane_L.d += std::copysign(0.5, r) * points[i].sigma_m;
        }
      }
      const PointToSweepPlaneGroupFactor group(points, kGravity, loss);
      double distances[5];
      group.WhitenedDistances(state.Blocks().data(), distances);
      const test::Evaluation robust = test::Evaluate(group, state.Blocks());
      const std::unique_ptr<ceres::LossFunction> rho(MakeLossFunction(loss));
      for (int i = 0; i < 5; ++i) {
        double value[3];
        rho->Evaluate(distances[i] * distances[i], value);
        // r~^2 = rho(r^2): the block's cost is the robust cost of its points.
        EXPECT_NEAR(robust.residual(i) * robust.residual(i), value[0], 1e-9 * value[0]);
        EXPECT_EQ(std::signbit(robust.residual(i)), std::signbit(distances[i]));
      }
      EXPECT_NEAR(distances[0], 0.3, 1e-6);
      // Ridders from a first step of 1e-6 relative: the rows bend within a sigma (2 cm).
      ceres::NumericDiffOptions small_steps;
      small_steps.ridders_relative_initial_step_size = 1e-6;
      test::ExpectGradientCheckPasses(group, Manifolds(&quaternion), state.Blocks(), 1e-5,
                                      "trial " + std::to_string(trial), small_steps);
    }
  }
}

// EvaluateTangent: the same rows, and the Jacobian in 22 tangent columns (column-major) that
// lift to the nine blocks' Jacobians: a quaternion's three columns times its
// QuaternionMinusJacobian, p_j's minus p_k's; with and without a loss.
TEST(PointToSweepPlaneGroupFactor, TangentJacobianLiftsToTheBlocks) {
  std::mt19937 rng(7);
  constexpr int kTangent = PointToSweepPlaneGroupFactor::kTangentColumns;
  // Each block's first column in the tangent columns (p_j: p_k's), and its sign.
  const int first_column[9] = {0, 3, 6, 9, 3, 12, 15, 18, 21};
  for (const LossOptions& loss : {LossOptions(), LossOptions{RobustLoss::kHuber, 1.0}}) {
    const std::vector<PointToSweepPlaneMeasurement> points = RandomGroup(6, &rng);
    const PointToSweepPlaneGroupFactor group(points, kGravity, loss);
    State state = RandomState(&rng);
    const std::vector<double*> values = state.Blocks();
    const test::Evaluation blocks = test::Evaluate(group, values);
    Eigen::VectorXd residuals(6);
    Eigen::Matrix<double, Eigen::Dynamic, kTangent> tangent(6, kTangent);
    tangent.setConstant(std::nan(""));
    ASSERT_TRUE(group.EvaluateTangent(values.data(), residuals.data(), tangent.data()));
    EXPECT_EQ(residuals, blocks.residual);
    ASSERT_EQ(blocks.jacobians.size(), 9u);
    for (size_t b = 0; b < 9; ++b) {
      const Eigen::MatrixXd& expected = blocks.jacobians[b];
      Eigen::MatrixXd lifted;
      if (expected.cols() == 4) {
        lifted =
            tangent.middleCols<3>(first_column[b]) * geometry::QuaternionMinusJacobian(values[b]);
      } else {
        lifted = tangent.middleCols(first_column[b], expected.cols());
        if (b == 4) lifted = -lifted;
      }
      EXPECT_LT((lifted - expected).norm(), 1e-12 * (1.0 + expected.norm())) << "block " << b;
    }
  }
}

TEST(PointToSweepPlaneGroupFactor, AnEmptyGroupIsRefused) {
  EXPECT_THROW(PointToSweepPlaneGroupFactor({}, kGravity, LossOptions()), Error);
  EXPECT_THROW(PointToSweepPlaneGroupFactor(std::vector<PointToSweepPlaneFactor::Terms>(), {},
                                            LossOptions()),
               Error);
}

// The points of a run with one plane motion (a sweep's points paired with one partner in one
// association) share one plane side, and evaluate as the point factors do.
TEST(PointToSweepPlaneGroupFactor, PointsOfOnePlaneMotionShareItsSide) {
  std::mt19937 rng(12);
  std::vector<PointToSweepPlaneMeasurement> points = RandomGroup(9, &rng);
  const std::vector<uint32_t> run = {0, 0, 0, 1, 1, 1, 1, 2, 2};
  for (size_t i = 1; i < points.size(); ++i) {
    if (run[i] == run[i - 1]) points[i].plane_motion = points[i - 1].plane_motion;
  }
  const PointToSweepPlaneGroupFactor group(points, kGravity, LossOptions());
  ASSERT_EQ(group.plane_sides().size(), 3u);
  State state = RandomState(&rng);
  const test::Evaluation stacked = test::Evaluate(group, state.Blocks());
  for (size_t i = 0; i < points.size(); ++i) {
    EXPECT_EQ(group.points()[i].plane_side(), run[i]);
    const PointToSweepPlaneFactor single(points[i], kGravity);
    const test::Evaluation one = test::Evaluate(single, state.Blocks());
    EXPECT_EQ(stacked.residual(static_cast<Eigen::Index>(i)), one.residual(0));
    for (size_t b = 0; b < one.jacobians.size(); ++b) {
      EXPECT_EQ(stacked.jacobians[b].row(static_cast<Eigen::Index>(i)), one.jacobians[b].row(0))
          << "point " << i;
    }
  }
}

TEST(PointToSweepPlaneGroupFactor, APlaneSideOutOfRangeIsRefused) {
  std::mt19937 rng(13);
  const PointToSweepPlaneMeasurement m = RandomMeasurement(&rng);
  std::vector<PointToSweepPlaneFactor::Terms> points = {
      PointToSweepPlaneFactor::Terms(m, kGravity, 1)};
  std::vector<PointToSweepPlaneFactor::Side> sides = {
      PointToSweepPlaneFactor::Side(m.plane_motion, kGravity)};
  EXPECT_THROW(PointToSweepPlaneGroupFactor(points, sides, LossOptions()), Error);
  points[0].set_plane_side(0);
  EXPECT_NO_THROW(PointToSweepPlaneGroupFactor(points, sides, LossOptions()));
}

// A released group hands over its points' terms and plane sides as they were, and their
// storage, emptied, serves a new group that is the group built from the measurements: it
// carries nothing over.
TEST(PointToSweepPlaneGroupFactor, ReleasedPointsServeANewGroup) {
  std::mt19937 rng(9);
  const LossOptions loss{RobustLoss::kHuber, 1.0};
  const std::vector<PointToSweepPlaneMeasurement> first = RandomGroup(40, &rng);
  const std::vector<PointToSweepPlaneMeasurement> second = RandomGroup(25, &rng);
  State state = RandomState(&rng);
  auto old = std::make_unique<PointToSweepPlaneGroupFactor>(first, kGravity, loss);
  const test::Evaluation before = test::Evaluate(*old, state.Blocks());
  ReleasedPointGroup released = ReleasePoints(std::move(old));
  ASSERT_EQ(released.points.size(), first.size());
  ASSERT_EQ(released.plane_sides.size(), first.size());  // every plane motion differs
  const PointToSweepPlaneFactor::Terms* const reused = released.points.data();
  // The released terms make the same group again.
  const PointToSweepPlaneGroupFactor again(released.points, released.plane_sides, loss);
  const test::Evaluation after = test::Evaluate(again, state.Blocks());
  EXPECT_EQ(after.residual, before.residual);
  for (size_t k = 0; k < after.jacobians.size(); ++k) {
    EXPECT_EQ(after.jacobians[k], before.jacobians[k]);
  }
  std::vector<PointToSweepPlaneFactor::Terms> storage = std::move(released.points);
  storage.clear();
  std::vector<PointToSweepPlaneFactor::Side> sides;
  for (const PointToSweepPlaneMeasurement& m : second) {
    sides.emplace_back(m.plane_motion, kGravity);
    storage.emplace_back(m, kGravity, static_cast<uint32_t>(sides.size() - 1));
  }
  EXPECT_EQ(storage.data(), reused);
  const PointToSweepPlaneGroupFactor from_terms(std::move(storage), std::move(sides), loss);
  const PointToSweepPlaneGroupFactor from_measurements(second, kGravity, loss);
  ASSERT_EQ(from_terms.num_residuals(), 25);
  const test::Evaluation a = test::Evaluate(from_terms, state.Blocks());
  const test::Evaluation b = test::Evaluate(from_measurements, state.Blocks());
  EXPECT_EQ(a.residual, b.residual);
  for (size_t k = 0; k < a.jacobians.size(); ++k) EXPECT_EQ(a.jacobians[k], b.jacobians[k]);
  const ReleasedPointGroup none = ReleasePoints(nullptr);
  EXPECT_TRUE(none.points.empty());
  EXPECT_TRUE(none.plane_sides.empty());
}

}  // namespace
}  // namespace factors
}  // namespace autocal
