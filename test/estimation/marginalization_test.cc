#include "autocal/estimation/marginalization.h"

#include <ceres/ceres.h>
#include <ceres/gradient_checker.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/geometry/manifolds.h"
#include "autocal/geometry/so3.h"
#include "estimation/pose_chain.h"

namespace autocal {
namespace estimation {
namespace {

using geometry::Exp;
using test::kPoses;
using test::PoseChain;
using test::PoseChainProblem;
using test::SolveTightly;

// Batch optimum x*; marginalizing pose 0 at x* and re-solving the window from a perturbed
// start must return the batch solution for every kept state.
TEST(Marginalization, WindowWithPriorMatchesBatchSolution) {
  for (uint32_t seed : {1u, 2u, 3u}) {
    const PoseChainProblem chain(seed);
    PoseChain batch = chain.initial_values();
    ceres::Problem batch_problem;
    chain.Build(&batch_problem, &batch, false);
    SolveTightly(&batch_problem);

    PoseChain window = batch;
    ceres::Problem window_problem;
    chain.Build(&window_problem, &window, false);
    std::unique_ptr<MarginalizationPrior> prior =
        Marginalize(&window_problem, {window.q[0].coeffs().data(), window.p[0].data()});
    ASSERT_NE(prior, nullptr);
    EXPECT_EQ(prior->blocks().size(), 3u);  // q1, p1 and the lever arm
    window_problem.RemoveParameterBlock(window.q[0].coeffs().data());
    window_problem.RemoveParameterBlock(window.p[0].data());
    const std::vector<double*> kept = prior->parameter_pointers();
    window_problem.AddResidualBlock(prior.release(), nullptr, kept);

    for (int i = 1; i < kPoses; ++i) {
      window.q[i] = window.q[i] * Exp(Eigen::Vector3d(0.02, -0.01, 0.03));
      window.p[i] += Eigen::Vector3d(0.1, -0.05, 0.02);
    }
    window.lever += Eigen::Vector3d(-0.05, 0.05, 0.05);
    SolveTightly(&window_problem);

    for (int i = 1; i < kPoses; ++i) {
      EXPECT_LT(geometry::AngularDistance(window.q[i], batch.q[i]), 1e-7)
          << "seed " << seed << " pose " << i;
      EXPECT_LT((window.p[i] - batch.p[i]).norm(), 1e-7)
          << "seed " << seed << " pose " << i << ": window " << window.p[i].transpose() << " batch "
          << batch.p[i].transpose();
    }
    EXPECT_LT((window.lever - batch.lever).norm(), 1e-7)
        << "window " << window.lever.transpose() << " batch " << batch.lever.transpose();
  }
}

// ---- A linear-Gaussian chain: marginalization is exact at ANY linearization point.

struct LinearChain {
  static constexpr int kStates = 5;
  std::array<Eigen::Vector3d, kStates> x;
  Eigen::Vector3d c;
};

struct DifferenceResidual {  // (x_j - x_i - u) / sigma, first `rows` components only
  DifferenceResidual(const Eigen::Vector3d& u, int rows) : u_(u), rows_(rows) {}
  bool operator()(double const* const* x, double* r) const {
    for (int k = 0; k < rows_; ++k) r[k] = (x[1][k] - x[0][k] - u_[k]) / 0.1;
    return true;
  }
  Eigen::Vector3d u_;
  int rows_;
};

struct OffsetResidual {  // (x + c - z) / sigma
  explicit OffsetResidual(const Eigen::Vector3d& z) : z_(z) {}
  bool operator()(const double* x, const double* c, double* r) const {
    for (int k = 0; k < 3; ++k) r[k] = (x[k] + c[k] - z_[k]) / 0.2;
    return true;
  }
  Eigen::Vector3d z_;
};

struct AbsoluteResidual {  // (x - z) / sigma, first `rows` components only
  AbsoluteResidual(const Eigen::Vector3d& z, int rows) : z_(z), rows_(rows) {}
  bool operator()(double const* const* x, double* r) const {
    for (int k = 0; k < rows_; ++k) r[k] = (x[0][k] - z_[k]) / 0.3;
    return true;
  }
  Eigen::Vector3d z_;
  int rows_;
};

void BuildLinear(ceres::Problem* problem, LinearChain* v, int first_rows) {
  std::mt19937 rng(9);
  std::normal_distribution<double> n(0.0, 1.0);
  for (int i = 0; i + 1 < LinearChain::kStates; ++i) {
    const Eigen::Vector3d u(1.0 + 0.1 * n(rng), 0.1 * n(rng), 0.1 * n(rng));
    const int rows = i == 0 ? first_rows : 3;
    auto* cost = new ceres::DynamicNumericDiffCostFunction<DifferenceResidual>(
        new DifferenceResidual(u, rows));
    cost->AddParameterBlock(3);
    cost->AddParameterBlock(3);
    cost->SetNumResiduals(rows);
    problem->AddResidualBlock(cost, nullptr, v->x[i].data(), v->x[i + 1].data());
  }
  // x_0's own measurement: all three components, or only `first_rows` of them.
  auto* absolute = new ceres::DynamicNumericDiffCostFunction<AbsoluteResidual>(
      new AbsoluteResidual(Eigen::Vector3d(0.1, -0.2, 0.3), first_rows));
  absolute->AddParameterBlock(3);
  absolute->SetNumResiduals(first_rows);
  problem->AddResidualBlock(absolute, nullptr, v->x[0].data());
  for (int i = 1; i < LinearChain::kStates; ++i) {
    const Eigen::Vector3d z(i + 0.2 * n(rng), 0.2 * n(rng), 3.0 + 0.2 * n(rng));
    problem->AddResidualBlock(
        new ceres::NumericDiffCostFunction<OffsetResidual, ceres::CENTRAL, 3, 3, 3>(
            new OffsetResidual(z)),
        nullptr, v->x[i].data(), v->c.data());
  }
  // A prior on c fixes the direction (all x_i + e, c - e) that the offsets cannot see.
  auto* c_prior = new ceres::DynamicNumericDiffCostFunction<AbsoluteResidual>(
      new AbsoluteResidual(Eigen::Vector3d(0.0, 0.0, 3.0), 3));
  c_prior->AddParameterBlock(3);
  c_prior->SetNumResiduals(3);
  problem->AddResidualBlock(c_prior, nullptr, v->c.data());
}

LinearChain RandomLinearValues() {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-5.0, 5.0);
  LinearChain v;
  for (auto& x : v.x) x = Eigen::Vector3d(u(rng), u(rng), u(rng));
  v.c = Eigen::Vector3d(u(rng), u(rng), u(rng));
  return v;
}

// States first_state... and c of `estimate` equal the batch solution's to 1e-8.
void ExpectSameLinearChain(const LinearChain& estimate, const LinearChain& batch, int first_state) {
  for (int i = first_state; i < LinearChain::kStates; ++i) {
    EXPECT_LT((estimate.x[i] - batch.x[i]).norm(), 1e-8)
        << "state " << i << " estimate " << estimate.x[i].transpose() << " batch "
        << batch.x[i].transpose();
  }
  EXPECT_LT((estimate.c - batch.c).norm(), 1e-8);
}

void ExpectLinearWindowMatchesBatch(int first_rows) {
  LinearChain batch = RandomLinearValues();
  ceres::Problem batch_problem;
  BuildLinear(&batch_problem, &batch, first_rows);
  SolveTightly(&batch_problem);

  LinearChain window = RandomLinearValues();  // linearized far from the optimum
  ceres::Problem window_problem;
  BuildLinear(&window_problem, &window, first_rows);
  std::unique_ptr<MarginalizationPrior> prior = Marginalize(&window_problem, {window.x[0].data()});
  ASSERT_NE(prior, nullptr);
  ASSERT_TRUE(prior->sqrt_information().allFinite());
  window_problem.RemoveParameterBlock(window.x[0].data());
  const std::vector<double*> kept = prior->parameter_pointers();
  window_problem.AddResidualBlock(prior.release(), nullptr, kept);
  SolveTightly(&window_problem);

  ExpectSameLinearChain(window, batch, 1);
}

TEST(Marginalization, ExactForLinearProblemsAtAnyLinearizationPoint) {
  ExpectLinearWindowMatchesBatch(3);
}

// x_0's z component is not observed by any factor: H_mm is singular, and the pseudo-inverse
// must keep the prior finite and exact for the observed directions.
TEST(Marginalization, RankDeficientMarginalizedBlockIsSafe) { ExpectLinearWindowMatchesBatch(2); }

// Marginalizes `blocks` (one state) out of the problem: returns its conditional, replaces its
// factors by the prior.
MarginalConditional MarginalizeInto(ceres::Problem* problem, const std::vector<double*>& blocks) {
  MarginalConditional conditional;
  std::unique_ptr<MarginalizationPrior> prior = Marginalize(problem, blocks, {}, &conditional);
  for (double* block : blocks) problem->RemoveParameterBlock(block);
  if (prior != nullptr) {
    const std::vector<double*> kept = prior->parameter_pointers();
    problem->AddResidualBlock(prior.release(), nullptr, kept);
  }
  return conditional;
}

// Each conditional applied, newest first, at the current values of its kept blocks (the
// blocks live on in the test, so their addresses still name them).
void SmoothBackwards(const std::vector<MarginalConditional>& conditionals) {
  for (auto it = conditionals.rbegin(); it != conditionals.rend(); ++it) {
    std::vector<const double*> kept;
    for (const PriorBlock& block : it->kept_blocks()) kept.push_back(block.values);
    std::vector<double*> marginalized;
    for (const PriorBlock& block : it->marginalized_blocks()) marginalized.push_back(block.values);
    it->Apply(kept, marginalized);
  }
}

// Marginalizing x_0 ... x_3 in turn, each at values far from the optimum, solving what is
// left and smoothing back with the conditionals (Eq. M4) gives every state of the batch
// solution: the smoother is exact for linear-Gaussian problems.
TEST(Marginalization, ConditionalsSmoothALinearChainToTheBatchSolution) {
  LinearChain batch = RandomLinearValues();
  ceres::Problem batch_problem;
  BuildLinear(&batch_problem, &batch, 3);
  SolveTightly(&batch_problem);

  LinearChain window = RandomLinearValues();
  ceres::Problem window_problem;
  BuildLinear(&window_problem, &window, 3);
  std::vector<MarginalConditional> conditionals;
  for (int i = 0; i + 1 < LinearChain::kStates; ++i) {
    conditionals.push_back(MarginalizeInto(&window_problem, {window.x[i].data()}));
    ASSERT_EQ(conditionals.back().marginalized_blocks().size(), 1u);
    // x_1 (x_0's factors do not reach c), then x_{i+1} and c.
    ASSERT_EQ(conditionals.back().kept_blocks().size(), i == 0 ? 1u : 2u);
  }
  SolveTightly(&window_problem);
  SmoothBackwards(conditionals);
  ExpectSameLinearChain(window, batch, 0);
}

// The nonlinear pose chain as a window of two poses that grows with time: solve, marginalize
// the older pose, add the next. The final window is off the batch optimum by the error of the
// priors' first estimates (the first windows start 0.3 m off and see few factors); the poses
// as they were marginalized (filtered) are off by more. Smoothed back from the final window,
// every pose comes to within that final window's error. Measured, seeds 1 / 2 / 3 (largest
// position error over the marginalized poses): filtered 34 / 36 / 46 mm, smoothed
// 12.6 / 5.3 / 20.9 mm, the final window's pose 15.8 / 6.4 / 24.1 mm.
TEST(Marginalization, ConditionalsCarryTheFinalWindowBackOverANonlinearPoseChain) {
  for (uint32_t seed : {1u, 2u, 3u}) {
    const PoseChainProblem chain(seed);
    PoseChain batch = chain.initial_values();
    ceres::Problem batch_problem;
    chain.Build(&batch_problem, &batch, false);
    SolveTightly(&batch_problem);

    PoseChain window = chain.initial_values();
    ceres::Problem window_problem;
    chain.AddPose(&window_problem, &window, 0);
    chain.AddPose(&window_problem, &window, 1);
    std::vector<MarginalConditional> conditionals;
    PoseChain filtered = window;
    for (int i = 0; i + 1 < kPoses; ++i) {
      SolveTightly(&window_problem);
      filtered.q[i] = window.q[i];
      filtered.p[i] = window.p[i];
      conditionals.push_back(
          MarginalizeInto(&window_problem, {window.q[i].coeffs().data(), window.p[i].data()}));
      if (i + 2 < kPoses) chain.AddPose(&window_problem, &window, i + 2);
    }
    SolveTightly(&window_problem);
    SmoothBackwards(conditionals);

    const int last = kPoses - 1;
    const double final_window_error = (window.p[last] - batch.p[last]).norm();
    double filtered_error = 0.0;
    double smoothed_error = 0.0;
    for (int i = 0; i < last; ++i) {
      filtered_error = std::max(filtered_error, (filtered.p[i] - batch.p[i]).norm());
      smoothed_error = std::max(smoothed_error, (window.p[i] - batch.p[i]).norm());
      // The chain turns as one: its poses share the final window's rotation error (up to
      // 1.005 times it, measured).
      EXPECT_LT(geometry::AngularDistance(window.q[i], batch.q[i]),
                1.05 * geometry::AngularDistance(window.q[last], batch.q[last]))
          << "seed " << seed << " pose " << i;
    }
    EXPECT_LT(smoothed_error, final_window_error) << "seed " << seed;
    EXPECT_LT(smoothed_error, 0.6 * filtered_error) << "seed " << seed;
  }
}

TEST(MarginalConditional, ApplyNamesAWrongNumberOfBlocks) {
  LinearChain v = RandomLinearValues();
  ceres::Problem problem;
  BuildLinear(&problem, &v, 3);
  const MarginalConditional conditional = MarginalizeInto(&problem, {v.x[0].data()});
  try {
    conditional.Apply({v.x[1].data(), v.c.data()}, {v.x[0].data()});
    FAIL() << "expected autocal::Error";
  } catch (const Error& e) {
    EXPECT_NE(
        std::string(e.what()).find("given 2 kept and 1 marginalized blocks, expected 1 and 1"),
        std::string::npos)
        << e.what();
  }
}

TEST(MarginalizationPrior, JacobiansPassGradientChecker) {
  const PoseChainProblem chain(4);
  PoseChain x = chain.initial_values();
  ceres::Problem problem;
  chain.Build(&problem, &x, false);
  std::unique_ptr<MarginalizationPrior> prior =
      Marginalize(&problem, {x.q[0].coeffs().data(), x.p[0].data()});
  ASSERT_NE(prior, nullptr);
  const geometry::RightQuaternionManifold quaternion;
  std::vector<const ceres::Manifold*> manifolds;
  for (const PriorBlock& block : prior->blocks()) {
    manifolds.push_back(block.manifold == nullptr ? nullptr : &quaternion);
  }
  // Probe away from the linearization point so that Jr^-1(dx) matters.
  PoseChain moved = x;
  moved.q[1] = moved.q[1] * Exp(Eigen::Vector3d(0.3, -0.2, 0.4));
  moved.p[1] += Eigen::Vector3d(0.5, 0.1, -0.2);
  moved.lever += Eigen::Vector3d(0.1, 0.0, 0.3);
  const std::vector<const double*> params = {moved.q[1].coeffs().data(), moved.p[1].data(),
                                             moved.lever.data()};
  // The prior's rows with little weight on a block hold exact zeros that finite differences
  // see as 1e-15 noise, so the per-entry verdict of Probe() is meaningless there; compare
  // each block's tangent Jacobian as a matrix instead.
  const ceres::GradientChecker checker(prior.get(), &manifolds, ceres::NumericDiffOptions());
  ceres::GradientChecker::ProbeResults results;
  checker.Probe(params.data(), 1e-7, &results);
  ASSERT_EQ(results.local_jacobians.size(), 3u);
  for (size_t i = 0; i < 3; ++i) {
    const Eigen::MatrixXd& analytic = results.local_jacobians[i];
    const Eigen::MatrixXd& numeric = results.local_numeric_jacobians[i];
    EXPECT_LT((analytic - numeric).norm(), 1e-7 * numeric.norm()) << "block " << i << "\nanalytic\n"
                                                                  << analytic << "\nnumeric\n"
                                                                  << numeric;
  }
}

}  // namespace
}  // namespace estimation
}  // namespace autocal
