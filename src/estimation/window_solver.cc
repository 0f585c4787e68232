#include "estimation/window_solver.h"

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <unordered_map>
#include <utility>

#include "autocal/common/error.h"
#include "autocal/geometry/manifolds.h"
#include "autocal/geometry/so3.h"
#include "estimation/normal_equations.h"

namespace autocal {
namespace estimation {
namespace internal {

namespace {

struct VariableBlock {
  double* values = nullptr;
  int ambient_size = 0;
  int tangent_size = 0;
  int offset = 0;
  const ceres::Manifold* manifold = nullptr;  // nullptr or a RightQuaternionManifold
  Eigen::VectorXd x0;
};

// The variable blocks of a pass and their values at its start, x = x0 [+] delta.
struct PassVariables {
  std::vector<VariableBlock> blocks;
  BlockOffsets offsets;
  std::unordered_map<const double*, size_t> index_of;
  int n = 0;  // tangent coordinates

  void SetValues(const Eigen::VectorXd& delta) const {
    for (const VariableBlock& block : blocks) {
      if (block.manifold == nullptr) {
        Eigen::Map<Eigen::VectorXd>(block.values, block.ambient_size) =
            block.x0 + delta.segment(block.offset, block.tangent_size);
      } else {
        block.manifold->Plus(block.x0.data(), delta.data() + block.offset, block.values);
      }
    }
  }
};

// The variable blocks in the order the residual blocks first name them
// (Problem::GetParameterBlocks orders them by address, which differs from run to run and
// with it the rounding of the solve).
PassVariables CollectVariables(ceres::Problem* problem,
                               const std::vector<ceres::ResidualBlockId>& all_rows) {
  PassVariables vars;
  std::vector<double*> row_blocks;
  for (ceres::ResidualBlockId id : all_rows) {
    problem->GetParameterBlocksForResidualBlock(id, &row_blocks);
    for (double* p : row_blocks) {
      if (vars.offsets.count(p) != 0 || problem->IsParameterBlockConstant(p)) continue;
      VariableBlock block;
      block.values = p;
      block.ambient_size = problem->ParameterBlockSize(p);
      block.tangent_size = problem->ParameterBlockTangentSize(p);
      block.manifold = problem->GetManifold(p);
      block.offset = vars.n;
      block.x0 = Eigen::Map<const Eigen::VectorXd>(p, block.ambient_size);
      if (block.manifold != nullptr &&
          dynamic_cast<const geometry::RightQuaternionManifold*>(block.manifold) == nullptr) {
        throw Error("window solver: supports Euclidean and RightQuaternionManifold blocks only");
      }
      vars.offsets[p] = vars.n;
      vars.index_of[p] = vars.blocks.size();
      vars.n += block.tangent_size;
      vars.blocks.push_back(std::move(block));
    }
  }
  return vars;
}

// The first-order model of the rows fixed for the pass (Eq. W5):
// cost(delta) = c0 + b0^T delta + 1/2 delta^T H0 delta. Only the lower triangles of the
// normal equations are formed and read (Cholesky and the symmetric products need no more).
// Returns c0.
double FixedRowsModel(ceres::Problem* problem, const std::vector<ceres::ResidualBlockId>& all_rows,
                      const std::vector<ceres::ResidualBlockId>& relinearized,
                      const PassVariables& vars, Eigen::MatrixXd* H0, Eigen::VectorXd* b0) {
  const std::set<ceres::ResidualBlockId> relinearized_set(relinearized.begin(), relinearized.end());
  std::vector<ceres::ResidualBlockId> fixed_rows;
  for (ceres::ResidualBlockId id : all_rows) {
    if (relinearized_set.count(id) == 0) fixed_rows.push_back(id);
  }
  H0->setZero(vars.n, vars.n);
  b0->setZero(vars.n);
  return AccumulateNormalEquations(problem, fixed_rows, vars.offsets, H0, b0, "window solver");
}

// The relinearized rows at delta `at`, their Jacobians taken to delta coordinates (with
// x = x0 Exp(delta), x0 Exp(delta + e) = x Exp(Jr(delta) e)): their cost, and their normal
// equations in delta coordinates.
void Relinearize(ceres::Problem* problem, const std::vector<ceres::ResidualBlockId>& relinearized,
                 const PassVariables& vars, const Eigen::VectorXd& at,
                 WindowSolverWorkspace::Relinearized* out) {
  const int n = vars.n;
  if (out->H.rows() != n) out->H.setZero(n, n);
  out->H.triangularView<Eigen::Lower>().setZero();
  out->b.setZero(n);
  out->cost = AccumulateNormalEquations(
      problem, relinearized, vars.offsets, &out->H, &out->b, "window solver",
      [&](const double* block, RowMajorMatrix* jacobian) {
        const VariableBlock& v = vars.blocks[vars.index_of.at(block)];
        if (v.manifold == nullptr) return;
        const Eigen::Vector3d d = at.segment<3>(v.offset);
        *jacobian = *jacobian * geometry::RightJacobian(d);
      });
}

}  // namespace

WindowSolverSummary SolveWindowPass(ceres::Problem* problem,
                                    const std::vector<ceres::ResidualBlockId>& relinearized,
                                    const WindowSolverOptions& options,
                                    WindowSolverWorkspace* workspace) {
  WindowSolverWorkspace local;
  WindowSolverWorkspace& ws = workspace != nullptr ? *workspace : local;
  std::vector<ceres::ResidualBlockId> all_rows;
  problem->GetResidualBlocks(&all_rows);
  const PassVariables vars = CollectVariables(problem, all_rows);
  WindowSolverSummary summary;
  const int n = vars.n;
  if (n == 0) return summary;
  Eigen::MatrixXd& H0 = ws.H0;
  Eigen::VectorXd& b0 = ws.b0;
  const double c0 = FixedRowsModel(problem, all_rows, relinearized, vars, &H0, &b0);

  Eigen::VectorXd delta = Eigen::VectorXd::Zero(n);
  Eigen::VectorXd H0_delta = Eigen::VectorXd::Zero(n);  // H0 delta
  WindowSolverWorkspace::Relinearized& current = ws.current;
  WindowSolverWorkspace::Relinearized& trial = ws.trial;
  Relinearize(problem, relinearized, vars, delta, &current);
  double cost = c0 + current.cost;
  summary.initial_cost = cost;

  // Levenberg-Marquardt on delta. A = H + D, the damped H = H0 + H(delta) (lower triangle;
  // its upper one stays zero).
  double radius = options.initial_trust_region_radius;
  double decrease_factor = 2.0;
  Eigen::MatrixXd& A = ws.A;
  if (A.rows() != n) A.setZero(n, n);
  Eigen::LLT<Eigen::MatrixXd>& llt = ws.llt;
  while (summary.iterations < options.max_iterations) {
    const Eigen::VectorXd g = b0 + H0_delta + current.b;
    if (g.lpNorm<Eigen::Infinity>() <= options.gradient_tolerance) break;
    A.triangularView<Eigen::Lower>() = H0 + current.H;
    const Eigen::VectorXd damping = A.diagonal().cwiseMax(1e-6).cwiseMin(1e32) / radius;
    A.diagonal() += damping;
    llt.compute(A);
    ++summary.iterations;
    if (llt.info() != Eigen::Success) {
      radius /= decrease_factor;
      decrease_factor *= 2.0;
      continue;
    }
    const Eigen::VectorXd step = -llt.solve(g);
    if (step.norm() <= options.parameter_tolerance * (delta.norm() + options.parameter_tolerance)) {
      break;
    }
    const Eigen::VectorXd H_step =
        A.selfadjointView<Eigen::Lower>() * step - damping.cwiseProduct(step);
    const double model_decrease = -(g.dot(step) + 0.5 * step.dot(H_step));
    const Eigen::VectorXd delta_trial = delta + step;
    const Eigen::VectorXd H0_delta_trial = H0.selfadjointView<Eigen::Lower>() * delta_trial;
    vars.SetValues(delta_trial);
    double trial_cost = std::numeric_limits<double>::infinity();
    try {
      Relinearize(problem, relinearized, vars, delta_trial, &trial);
      // The fixed rows' first-order model: c0 + b0^T delta + 1/2 delta^T H0 delta.
      trial_cost = c0 + b0.dot(delta_trial) + 0.5 * delta_trial.dot(H0_delta_trial) + trial.cost;
    } catch (const Error&) {
      // A step to where a factor cannot be evaluated is rejected.
    }
    const double rho = (cost - trial_cost) / model_decrease;
    if (model_decrease > 0.0 && std::isfinite(trial_cost) && rho > 1e-3) {
      const double relative_decrease = (cost - trial_cost) / cost;
      delta = delta_trial;
      H0_delta = H0_delta_trial;
      std::swap(current, trial);
      cost = trial_cost;
      ++summary.successful_steps;
      radius = std::min(1e16, radius / std::max(1.0 / 3.0, 1.0 - std::pow(2.0 * rho - 1.0, 3)));
      decrease_factor = 2.0;
      if (relative_decrease <= options.function_tolerance) break;
    } else {
      vars.SetValues(delta);
      radius /= decrease_factor;
      decrease_factor *= 2.0;
    }
  }
  vars.SetValues(delta);
  summary.final_cost = cost;
  return summary;
}

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
