#pragma once

// The window's Levenberg-Marquardt solve of one pass (docs/sliding_window.md, "The window's
// Levenberg-Marquardt", Eq. W5). Within a pass most rows are first-order models fixed at the pass's
// start ("Linearized once per pass"): their normal equations are formed once per pass, and an
// iteration only evaluates the rows that are relinearized (the IMU factors, rows with a robust
// loss) and solves the dense system.

#include <ceres/ceres.h>

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <vector>

#include "autocal/estimation/sliding_window_options.h"

namespace autocal {
namespace estimation {
namespace internal {

struct WindowSolverSummary {
  int iterations = 0;  // accepted + rejected steps
  int successful_steps = 0;
  double initial_cost = 0.0;
  double final_cost = 0.0;
};

// The dense buffers of a solve (about 5 n^2 doubles for n tangent coordinates). Kept by the
// caller across passes, they are allocated once instead of at every pass and iteration: a
// fresh n x n buffer is a fresh page of memory at every touch when the allocator returned the
// last one to the system.
struct WindowSolverWorkspace {
  Eigen::MatrixXd H0, A;  // the fixed rows' H; the damped H0 + H(delta)
  Eigen::VectorXd b0;
  struct Relinearized {
    double cost = 0.0;
    Eigen::MatrixXd H;
    Eigen::VectorXd b;
  } current, trial;  // the relinearized rows at the accepted point and at the trial
  Eigen::LLT<Eigen::MatrixXd> llt;
};

// Minimizes the cost of `problem` over its variable blocks, leaving the solution in them.
// Coordinates are delta = x [-] x0 from the values x0 the pass starts at, x = x0 [+] delta.
// Every residual block not in `relinearized` is evaluated once, at x0, and enters as its
// first-order model r0 + J0 delta; those in `relinearized` are evaluated at every iteration,
// their Jacobians carried into delta coordinates (J Jr(delta) for a RightQuaternionManifold
// block). Blocks with a robust loss belong in `relinearized` (the model of the others keeps
// the loss's weights from x0). Supported manifolds: none and geometry::RightQuaternionManifold.
// A trial step whose rows cannot be evaluated, or that does not lower the cost by at least
// 1e-3 of the model's decrease, is rejected (the values return to the accepted point and the
// damping grows), as is a step whose damped system cannot be factored. Throws autocal::Error
// when a residual block cannot be evaluated at x0.
// `workspace` may be nullptr (a local one is used) and holds nothing the result depends on.
WindowSolverSummary SolveWindowPass(ceres::Problem* problem,
                                    const std::vector<ceres::ResidualBlockId>& relinearized,
                                    const WindowSolverOptions& options,
                                    WindowSolverWorkspace* workspace = nullptr);

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
