#include "autocal/factors/point_to_plane_factor.h"

#include <ceres/gradient_checker.h>
#include <gtest/gtest.h>

#include <limits>
#include <memory>
#include <random>
#include <vector>

#include "analytic_motion.h"
#include "autocal/common/error.h"
#include "autocal/geometry/manifolds.h"
#include "autocal/geometry/so3.h"

namespace autocal {
namespace factors {
namespace {

using geometry::Exp;
using geometry::Hat;
using test::AnalyticTrajectory;
using test::kGravity;
using test::TrueMotion;

struct State {
  Eigen::Quaterniond q_W_I;
  Eigen::Vector3d p_W_I, v_W_I;
  Eigen::Quaterniond q_I_L;
  Eigen::Vector3d p_I_L;
  double offset_s;
  std::vector<const double*> Parameters() const {
    return {q_W_I.coeffs().data(), p_W_I.data(), v_W_I.data(),
            q_I_L.coeffs().data(), p_I_L.data(), &offset_s};
  }
};

// A true scene: the keyframe at t_k, the true extrinsic and offset, and a point measured at
// LiDAR time t_sweep + tau that truly lies on a plane with a random normal.
struct Scene {
  AnalyticTrajectory traj;
  State truth;
  double t_k = 2.0;
  double t_sweep_lidar = 1.96;  // LiDAR clock
  Eigen::Vector3d p_L;
  geometry::Plane plane;
  double tau = 0.0;

  Scene(std::mt19937* rng, double tau_s) : tau(tau_s) {
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    truth.q_W_I = traj.Rotation(t_k);
    truth.p_W_I = traj.Position(t_k);
    truth.v_W_I = traj.Velocity(t_k);
    truth.q_I_L = Exp(Eigen::Vector3d(0.05, -0.03, 1.2));
    truth.p_I_L = Eigen::Vector3d(0.4, -0.1, 0.3);
    truth.offset_s = 0.04;  // t_imu = t_lidar + 0.04 s
    p_L = Eigen::Vector3d(8.0 * u(*rng), 8.0 * u(*rng), 2.0 * u(*rng));
    const double t_true = t_sweep_lidar + tau + truth.offset_s;
    const Eigen::Vector3d p_W =
        traj.Rotation(t_true) * (truth.q_I_L * p_L + truth.p_I_L) + traj.Position(t_true);
    plane.normal = Eigen::Vector3d(u(*rng), u(*rng), u(*rng)).normalized();
    plane.d = -plane.normal.dot(p_W);
  }

  // The measurement as an estimator would build it, propagating at offset_0.
  PointToPlaneMeasurement Measurement(double offset_linearization_s) const {
    PointToPlaneMeasurement m;
    m.p_L = p_L;
    m.plane = plane;
    m.sigma_m = 0.03;
    m.offset_linearization_s = offset_linearization_s;
    m.motion = TrueMotion(traj, t_k, t_sweep_lidar + tau + offset_linearization_s - t_k);
    return m;
  }
};

double Residual(const ceres::CostFunction& cost, const State& state) {
  double r = 0.0;
  const std::vector<const double*> params = state.Parameters();
  EXPECT_TRUE(cost.Evaluate(params.data(), &r, nullptr));
  return r;
}

TEST(PointToPlaneFactor, ZeroAtGroundTruth) {
  std::mt19937 rng(1);
  for (double tau : {0.0, 0.031, 0.067, 0.099}) {
    const Scene scene(&rng, tau);
    const PointToPlaneFactor factor(scene.Measurement(scene.truth.offset_s), kGravity);
    EXPECT_NEAR(Residual(factor, scene.truth), 0.0, 1e-10) << "tau = " << tau;
  }
}

// A zero, negative or non-finite sigma is refused: it whitened every residual to inf or NaN.
TEST(PointToPlaneFactor, RefusesASigmaThatIsNotPositive) {
  std::mt19937 rng(1);
  const Scene scene(&rng, 0.031);
  for (double sigma_m : {0.0, -0.02, std::numeric_limits<double>::quiet_NaN(),
                         std::numeric_limits<double>::infinity()}) {
    PointToPlaneMeasurement m = scene.Measurement(scene.truth.offset_s);
    m.sigma_m = sigma_m;
    EXPECT_THROW(PointToPlaneFactor(m, kGravity), Error) << sigma_m;
  }
}

// Linearized at a wrong offset, the factor evaluated at the true offset is exact to first
// order: the error shrinks quadratically with the linearization error, and the sign of the
// offset matters (a flipped sign leaves a large residual).
TEST(PointToPlaneFactor, TimeOffsetModelIsFirstOrderAccurate) {
  std::mt19937 rng(2);
  const Scene scene(&rng, 0.05);
  const double error_coarse = std::abs(Residual(
      PointToPlaneFactor(scene.Measurement(scene.truth.offset_s - 0.004), kGravity), scene.truth));
  const double error_fine = std::abs(Residual(
      PointToPlaneFactor(scene.Measurement(scene.truth.offset_s - 0.002), kGravity), scene.truth));
  EXPECT_GT(error_coarse, 0.0);
  EXPECT_NEAR(error_coarse / error_fine, 4.0, 0.4)
      << "coarse " << error_coarse << " fine " << error_fine;

  State wrong_sign = scene.truth;
  wrong_sign.offset_s = -scene.truth.offset_s;
  const PointToPlaneFactor factor(scene.Measurement(-scene.truth.offset_s), kGravity);
  EXPECT_GT(std::abs(Residual(factor, wrong_sign)), 100.0 * error_coarse);
}

State RandomState(std::mt19937* rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  State s;
  s.q_W_I = Eigen::Quaterniond::UnitRandom();
  s.p_W_I = 50.0 * Eigen::Vector3d(u(*rng), u(*rng), u(*rng));
  s.v_W_I = 15.0 * Eigen::Vector3d(u(*rng), u(*rng), u(*rng));
  s.q_I_L = Eigen::Quaterniond::UnitRandom();
  s.p_I_L = Eigen::Vector3d(u(*rng), u(*rng), u(*rng));
  s.offset_s = 0.05 * u(*rng);
  return s;
}

PointToPlaneMeasurement RandomMeasurement(std::mt19937* rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  PointToPlaneMeasurement m;
  m.p_L = 20.0 * Eigen::Vector3d(u(*rng), u(*rng), u(*rng));
  m.motion.dt_s = 0.1 * (u(*rng) + 1.0);
  m.motion.delta_q = Exp(Eigen::Vector3d(0.3 * u(*rng), 0.3 * u(*rng), 0.3 * u(*rng)));
  m.motion.delta_v = 2.0 * Eigen::Vector3d(u(*rng), u(*rng), u(*rng));
  m.motion.delta_p = 2.0 * Eigen::Vector3d(u(*rng), u(*rng), u(*rng));
  m.motion.omega_rad_s = Eigen::Vector3d(u(*rng), u(*rng), u(*rng));
  m.plane.normal = Eigen::Vector3d(u(*rng), u(*rng), u(*rng)).normalized();
  m.plane.d = 10.0 * u(*rng);
  m.sigma_m = 0.02;
  m.offset_linearization_s = 0.03 * u(*rng);
  return m;
}

TEST(PointToPlaneFactor, JacobiansPassGradientChecker) {
  std::mt19937 rng(3);
  const geometry::RightQuaternionManifold quaternion;
  const std::vector<const ceres::Manifold*> manifolds = {&quaternion, nullptr, nullptr,
                                                         &quaternion, nullptr, nullptr};
  for (int trial = 0; trial < 50; ++trial) {
    const PointToPlaneMeasurement m = RandomMeasurement(&rng);
    const State state = RandomState(&rng);
    const PointToPlaneFactor factor(m, kGravity);
    const ceres::GradientChecker checker(&factor, &manifolds, ceres::NumericDiffOptions());
    ceres::GradientChecker::ProbeResults results;
    EXPECT_TRUE(checker.Probe(state.Parameters().data(), 1e-7, &results))
        << "trial " << trial << "\n"
        << results.error_log;
  }
}

TEST(PointToPlaneFactor, AnalyticMatchesAutodiffTwin) {
  std::mt19937 rng(4);
  constexpr int kSizes[] = {4, 3, 3, 4, 3, 1};
  for (int trial = 0; trial < 50; ++trial) {
    const PointToPlaneMeasurement m = RandomMeasurement(&rng);
    const State state = RandomState(&rng);
    const PointToPlaneFactor analytic(m, kGravity);
    const std::unique_ptr<ceres::CostFunction> autodiff(CreatePointToPlaneAutoDiff(m, kGravity));
    std::vector<std::vector<double>> j_a(6), j_b(6);
    std::vector<double*> ptr_a(6), ptr_b(6);
    for (int i = 0; i < 6; ++i) {
      j_a[i].assign(kSizes[i], 0.0);
      j_b[i].assign(kSizes[i], 0.0);
      ptr_a[i] = j_a[i].data();
      ptr_b[i] = j_b[i].data();
    }
    double r_a = 0.0, r_b = 0.0;
    const std::vector<const double*> params = state.Parameters();
    ASSERT_TRUE(analytic.Evaluate(params.data(), &r_a, ptr_a.data()));
    ASSERT_TRUE(autodiff->Evaluate(params.data(), &r_b, ptr_b.data()));
    EXPECT_NEAR(r_a, r_b, 1e-9 * std::max(1.0, std::abs(r_b)));
    // Quaternion blocks are compared in the tangent space: ambient Jacobians differ by
    // components normal to the manifold, which Ceres never sees.
    for (int i = 0; i < 6; ++i) {
      Eigen::RowVectorXd a = Eigen::Map<Eigen::RowVectorXd>(j_a[i].data(), kSizes[i]);
      Eigen::RowVectorXd b = Eigen::Map<Eigen::RowVectorXd>(j_b[i].data(), kSizes[i]);
      if (kSizes[i] == 4) {
        Eigen::Matrix<double, 4, 3, Eigen::RowMajor> plus;
        geometry::RightQuaternionManifold().PlusJacobian(params[i], plus.data());
        a = a * plus;
        b = b * plus;
      }
      EXPECT_LT((a - b).norm(), 1e-9 * std::max(1.0, b.norm()))
          << "trial " << trial << " block " << i << "\nanalytic " << a << "\nautodiff " << b;
    }
  }
}

}  // namespace
}  // namespace factors
}  // namespace autocal
