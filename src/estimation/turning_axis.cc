#include "estimation/turning_axis.h"

#include <Eigen/Eigenvalues>
#include <cmath>

namespace autocal {
namespace estimation {
namespace internal {

std::optional<Eigen::Vector3d> PrincipalTurningAxis(int n, const Eigen::Matrix3d& spread,
                                                    const Eigen::Vector3d& up_I,
                                                    double max_error_rad) {
  if (n < 3 || !(max_error_rad > 0.0)) return std::nullopt;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(spread);
  const double l1 = eigen.eigenvalues()(2), l2 = eigen.eigenvalues()(1);
  if (!(l1 > l2)) return std::nullopt;
  const double error_rad = std::sqrt(l1 * l2 / (n * (l1 - l2) * (l1 - l2)));
  if (!(error_rad < max_error_rad)) return std::nullopt;
  // The vehicle turns about its up axis: a spread whose principal axis is not the one nearest
  // up_I (a straight drive's pitching) says nothing about it.
  const Eigen::Vector3d along_up = (eigen.eigenvectors().transpose() * up_I).cwiseAbs();
  if (!(along_up(2) > along_up(1) && along_up(2) > along_up(0))) return std::nullopt;
  const Eigen::Vector3d axis = eigen.eigenvectors().col(2);
  return axis.dot(up_I) < 0.0 ? Eigen::Vector3d(-axis) : axis;
}

void TurningRateSpread::Add(const Eigen::Vector3d& rate_rad_s) {
  ++n_;
  const Eigen::Vector3d before = rate_rad_s - mean_;
  mean_ += before / n_;
  sum_sq_ += before * (rate_rad_s - mean_).transpose();
}

std::optional<Eigen::Vector3d> TurningRateSpread::Axis(const Eigen::Vector3d& up_I,
                                                       double max_error_rad) const {
  if (n_ == 0) return std::nullopt;
  // Welford's increments are symmetric only to rounding; the solver reads one triangle.
  const Eigen::Matrix3d spread = 0.5 * (sum_sq_ + sum_sq_.transpose()) / n_;
  return PrincipalTurningAxis(n_, spread, up_I, max_error_rad);
}

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
