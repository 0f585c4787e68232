#include "estimation/window_solver.h"

#include <ceres/ceres.h>
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <limits>
#include <vector>

#include "autocal/geometry/so3.h"
#include "estimation/normal_equations.h"
#include "estimation/pose_chain.h"

namespace autocal {
namespace estimation {
namespace internal {
namespace {

using test::kPoses;
using test::PoseChain;
using test::PoseChainProblem;

WindowSolverOptions Tight() {
  WindowSolverOptions options;
  options.max_iterations = 100;
  options.function_tolerance = 1e-16;
  options.gradient_tolerance = 1e-14;
  options.parameter_tolerance = 1e-14;
  return options;
}

// The chain's rows in `problem` (built at *x): all of them, and split into those with the
// (Huber) loss, the antenna rows, and those without.
struct ChainRows {
  std::vector<ceres::ResidualBlockId> all;
  std::vector<ceres::ResidualBlockId> with_loss;
  std::vector<ceres::ResidualBlockId> without_loss;
};

ChainRows BuildChain(const PoseChainProblem& chain, PoseChain* x, ceres::Problem* problem) {
  chain.Build(problem, x, false);
  ChainRows rows;
  problem->GetResidualBlocks(&rows.all);
  for (ceres::ResidualBlockId id : rows.all) {
    (problem->GetLossFunctionForResidualBlock(id) != nullptr ? rows.with_loss : rows.without_loss)
        .push_back(id);
  }
  return rows;
}

PoseChain CeresOptimum(const PoseChainProblem& chain) {
  PoseChain x = chain.initial_values();
  ceres::Problem problem;
  chain.Build(&problem, &x, false);
  test::SolveTightly(&problem);
  return x;
}

void ExpectSameChain(const PoseChain& a, const PoseChain& b, double tolerance) {
  for (int i = 0; i < kPoses; ++i) {
    EXPECT_LT(geometry::AngularDistance(a.q[i], b.q[i]), tolerance) << "pose " << i;
    EXPECT_LT((a.p[i] - b.p[i]).norm(), tolerance) << "pose " << i;
  }
  EXPECT_LT((a.lever - b.lever).norm(), tolerance);
}

// Every row relinearized: Levenberg-Marquardt on the whole nonlinear chain (quaternions, a
// Huber loss) from the perturbed start reaches the optimum Ceres finds.
TEST(WindowSolver, WithEveryRowRelinearizedFindsTheCeresOptimum) {
  for (uint32_t seed : {1u, 2u, 3u}) {
    const PoseChainProblem chain(seed);
    const PoseChain expected = CeresOptimum(chain);
    PoseChain x = chain.initial_values();
    ceres::Problem problem;
    const ChainRows rows = BuildChain(chain, &x, &problem);
    const WindowSolverSummary summary = SolveWindowPass(&problem, rows.all, Tight());
    EXPECT_GT(summary.successful_steps, 2);
    EXPECT_LT(summary.final_cost, summary.initial_cost);
    ExpectSameChain(x, expected, 1e-7);
  }
}

// The relative-pose rows fixed at their first-order model, the antenna rows (with the loss)
// relinearized: one pass minimizes the model, not the chain, so its result is off the optimum;
// passes that start where the previous one ended (Gauss-Newton on the fixed rows, as the window's
// passes, "Linearized once per pass") converge to it. This needs the model's gradient and Hessian
// at delta = 0 and the Jacobians of the relinearized rows in delta coordinates to be right.
TEST(WindowSolver, PassesOnFixedFirstOrderRowsConvergeToTheOptimum) {
  for (uint32_t seed : {1u, 2u, 3u}) {
    const PoseChainProblem chain(seed);
    const PoseChain expected = CeresOptimum(chain);
    PoseChain x = chain.initial_values();
    ceres::Problem problem;
    const std::vector<ceres::ResidualBlockId> with_loss = BuildChain(chain, &x, &problem).with_loss;
    ASSERT_EQ(with_loss.size(), static_cast<size_t>(kPoses));
    double first_pass_error = 0.0;
    for (int pass = 0; pass < 12; ++pass) {
      SolveWindowPass(&problem, with_loss, Tight());
      if (pass == 0) first_pass_error = (x.p[kPoses - 1] - expected.p[kPoses - 1]).norm();
    }
    EXPECT_GT(first_pass_error, 1e-4) << "one pass should not reach the optimum";
    ExpectSameChain(x, expected, 1e-7);
  }
}

// One pass, relative-pose rows fixed: the result is a stationary point of the pass's cost
// C(delta) = c0 + b0^T delta + 1/2 delta^T H0 delta + (antenna rows at x0 [+] delta), whose
// gradient is taken here by central differences in delta.
TEST(WindowSolver, OnePassEndsAtAStationaryPointOfItsModel) {
  for (uint32_t seed : {1u, 2u, 3u}) {
    const PoseChainProblem chain(seed);
    PoseChain x = chain.initial_values();
    const PoseChain x0 = x;
    ceres::Problem problem;
    const ChainRows rows = BuildChain(chain, &x, &problem);
    const std::vector<ceres::ResidualBlockId>& with_loss = rows.with_loss;
    const std::vector<ceres::ResidualBlockId>& fixed = rows.without_loss;
    // delta: q_i, p_i for every pose, then the lever arm.
    BlockOffsets offsets;
    for (int i = 0; i < kPoses; ++i) {
      offsets[x.q[i].coeffs().data()] = 6 * i;
      offsets[x.p[i].data()] = 6 * i + 3;
    }
    offsets[x.lever.data()] = 6 * kPoses;
    const int n = 6 * kPoses + 3;
    Eigen::MatrixXd H0 = Eigen::MatrixXd::Zero(n, n);
    Eigen::VectorXd b0 = Eigen::VectorXd::Zero(n);
    const double c0 = AccumulateNormalEquations(&problem, fixed, offsets, &H0, &b0, "test");
    H0.triangularView<Eigen::StrictlyUpper>() = H0.transpose();

    SolveWindowPass(&problem, with_loss, Tight());
    Eigen::VectorXd solution(n);
    for (int i = 0; i < kPoses; ++i) {
      solution.segment<3>(6 * i) = geometry::Log(Eigen::Quaterniond(x0.q[i].conjugate() * x.q[i]));
      solution.segment<3>(6 * i + 3) = x.p[i] - x0.p[i];
    }
    solution.tail<3>() = x.lever - x0.lever;

    const auto cost = [&](const Eigen::VectorXd& delta) {
      for (int i = 0; i < kPoses; ++i) {
        x.q[i] = x0.q[i] * geometry::Exp(Eigen::Vector3d(delta.segment<3>(6 * i)));
        x.p[i] = x0.p[i] + delta.segment<3>(6 * i + 3);
      }
      x.lever = x0.lever + delta.tail<3>();
      double c = c0 + b0.dot(delta) + 0.5 * delta.dot(H0 * delta);
      for (ceres::ResidualBlockId id : with_loss) {
        double row_cost = 0.0;
        EXPECT_TRUE(problem.EvaluateResidualBlock(id, true, &row_cost, nullptr, nullptr));
        c += row_cost;
      }
      return c;
    };
    const auto gradient = [&](const Eigen::VectorXd& delta) {
      Eigen::VectorXd g(n);
      for (int k = 0; k < n; ++k) {
        const double h = 1e-6;
        Eigen::VectorXd plus = delta, minus = delta;
        plus(k) += h;
        minus(k) -= h;
        g(k) = (cost(plus) - cost(minus)) / (2.0 * h);
      }
      return g;
    };
    const double start_gradient = gradient(Eigen::VectorXd::Zero(n)).lpNorm<Eigen::Infinity>();
    const double end_gradient = gradient(solution).lpNorm<Eigen::Infinity>();
    EXPECT_GT(solution.norm(), 1e-2) << "seed " << seed;
    EXPECT_LT(end_gradient, 1e-6 * start_gradient)
        << "seed " << seed << ": gradient " << start_gradient << " -> " << end_gradient;
  }
}

// r = x^2 - 4 (minimum at x = 2) and r = x - 10 behind a wall: no evaluation beyond x = 3.
class Scalar final : public ceres::SizedCostFunction<1, 1> {
 public:
  explicit Scalar(bool wall) : wall_(wall) {}
  bool Evaluate(double const* const* x, double* r, double** jacobians) const override {
    if (wall_ && x[0][0] > 3.0) return false;
    r[0] = wall_ ? x[0][0] - 10.0 : x[0][0] * x[0][0] - 4.0;
    if (jacobians != nullptr && jacobians[0] != nullptr) {
      jacobians[0][0] = wall_ ? 1.0 : 2.0 * x[0][0];
    }
    return true;
  }

 private:
  bool wall_;
};

// After any number of iterations the block holds an accepted point and the summary's cost is
// its cost: the first Gauss-Newton steps (to x = 20, and to 10 behind the wall) raise the
// cost or cannot be evaluated, are rejected and leave no trace; the cost never rises.
TEST(WindowSolver, RejectedStepsLeaveTheAcceptedPoint) {
  for (const bool wall : {false, true}) {
    double previous_cost = std::numeric_limits<double>::infinity();
    for (int iterations = 1; iterations <= 30; ++iterations) {
      double x = 0.1;
      ceres::Problem problem;
      const ceres::ResidualBlockId id = problem.AddResidualBlock(new Scalar(wall), nullptr, &x);
      WindowSolverOptions options = Tight();
      options.max_iterations = iterations;
      const WindowSolverSummary summary = SolveWindowPass(&problem, {id}, options);
      double cost = 0.0;
      ASSERT_TRUE(problem.EvaluateResidualBlock(id, false, &cost, nullptr, nullptr))
          << "left at x = " << x << " after " << iterations << " iterations";
      EXPECT_DOUBLE_EQ(cost, summary.final_cost) << "wall " << wall << ", " << iterations;
      EXPECT_LE(summary.final_cost, summary.initial_cost);
      EXPECT_LE(summary.final_cost, previous_cost) << "wall " << wall << ", " << iterations;
      previous_cost = summary.final_cost;
      if (iterations == 1) {
        EXPECT_EQ(summary.successful_steps, 0) << "wall " << wall;
      }
      if (iterations == 30) {  // at the minimum, or at the wall
        EXPECT_NEAR(x, wall ? 2.995 : 2.0, wall ? 5e-3 : 1e-6) << "wall " << wall;
      }
    }
  }
}

// A cap of zero iterations leaves every block at its value.
TEST(WindowSolver, ZeroIterationsLeaveTheValuesAlone) {
  const PoseChainProblem chain(4);
  PoseChain x = chain.initial_values();
  const PoseChain start = x;
  ceres::Problem problem;
  chain.Build(&problem, &x, false);
  WindowSolverOptions options;
  options.max_iterations = 0;
  SolveWindowPass(&problem, {}, options);
  ExpectSameChain(x, start, 1e-15);
}

}  // namespace
}  // namespace internal
}  // namespace estimation
}  // namespace autocal
