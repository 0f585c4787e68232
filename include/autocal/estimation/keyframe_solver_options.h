#pragma once

// The Ceres settings every keyframe graph is solved with (the batch, the joint solves of the
// pipeline, the GNSS-inertial keyframes): sparse normal Cholesky on Eigen's sparse
// Cholesky when Ceres has it, else SuiteSparse. A keyframe graph's normal matrix is a band
// (LiDAR partners up to 20 keyframes apart) plus the calibration's dense rows; on the 60 s
// urban batch Eigen's simplicial factorization took 2.7 s against CHOLMOD's 3.8 s with the
// same steps.
//
// The trust region starts at 1e8 instead of Ceres' 1e4: with Jacobi scaling the damping is the
// inverse radius, and the graph's weakly determined directions (those the drive barely
// excites, bounded by their priors) have scaled curvature far below 1e-4, so the default
// damped them and Levenberg-Marquardt crawled along them for 8-12 steps per outer iteration.
// From 1e8 the first step is nearly Gauss-Newton; a rejected step still shrinks the region.
// On three 60 s urban seeds the batch's steps went from 43 to 12 and the errors against the
// truth moved within their noise (0.0544 -> 0.0538 deg, -0.087 -> -0.089 ms on seed 1).

#include <ceres/ceres.h>

namespace autocal {
namespace estimation {

ceres::Solver::Options KeyframeSolverOptions(int max_iterations, int num_threads);

}  // namespace estimation
}  // namespace autocal
