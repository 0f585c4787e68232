#pragma once

// The Ceres settings every keyframe graph is solved with (the batch, the joint solves of the
// pipeline, the GNSS-inertial keyframes): sparse normal Cholesky on Eigen's sparse
// Cholesky when Ceres has it (faster on a keyframe graph's banded normal matrix), else
// SuiteSparse.
//
// The trust region starts at 1e8 instead of Ceres' 1e4: with Jacobi scaling the damping is the
// inverse radius, and the graph's weakly determined directions (those the drive barely
// excites, bounded by their priors) have scaled curvature far below 1e-4, so the default
// damped them and Levenberg-Marquardt crawled along them. From 1e8 the first step is nearly
// Gauss-Newton; a rejected step still shrinks the region. Figures: docs/history/estimation.md,
// "Keyframe solver settings".

#include <ceres/ceres.h>

namespace autocal {
namespace estimation {

ceres::Solver::Options KeyframeSolverOptions(int max_iterations, int num_threads);

}  // namespace estimation
}  // namespace autocal
