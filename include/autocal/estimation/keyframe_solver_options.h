#pragma once

// The Ceres settings every keyframe graph is solved with (the batch, the joint solves of the
// pipeline, the GNSS-inertial keyframes): sparse normal Cholesky on Eigen's sparse
// Cholesky when Ceres has it, else SuiteSparse. A keyframe graph's normal matrix is a band
// (LiDAR partners up to 20 keyframes apart) plus the calibration's dense rows; on the 60 s
// urban batch Eigen's simplicial factorization took 2.7 s against CHOLMOD's 3.8 s with the
// same steps.

#include <ceres/ceres.h>

namespace autocal {
namespace estimation {

ceres::Solver::Options KeyframeSolverOptions(int max_iterations, int num_threads);

}  // namespace estimation
}  // namespace autocal
