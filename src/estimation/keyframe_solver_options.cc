#include "autocal/estimation/keyframe_solver_options.h"

namespace autocal {
namespace estimation {

ceres::Solver::Options KeyframeSolverOptions(int max_iterations, int num_threads) {
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  if (ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::EIGEN_SPARSE)) {
    options.sparse_linear_algebra_library_type = ceres::EIGEN_SPARSE;
  }
  // Levenberg-Marquardt starting nearly at Gauss-Newton (header).
  options.initial_trust_region_radius = 1e8;
  options.max_num_iterations = max_iterations;
  options.num_threads = num_threads;
  return options;
}

}  // namespace estimation
}  // namespace autocal
