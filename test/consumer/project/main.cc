// A project that links the installed autocal package and uses its public API.
#include <ceres/ceres.h>

#include <cstdio>

#include "autocal/geometry/manifolds.h"
#include "autocal/geometry/se3.h"

namespace {
// Rotation error between q and a target, in the tangent space.
struct Residual {
  explicit Residual(const Eigen::Quaterniond& target) : target_(target) {}
  template <typename T>
  bool operator()(const T* q_xyzw, T* residual) const {
    const Eigen::Map<const Eigen::Quaternion<T>> q(q_xyzw);
    Eigen::Map<Eigen::Matrix<T, 3, 1>> r(residual);
    r = autocal::geometry::Log(Eigen::Quaternion<T>(target_.cast<T>().conjugate() * q));
    return true;
  }
  Eigen::Quaterniond target_;
};
}  // namespace

int main() {
  using autocal::geometry::Exp;
  using autocal::geometry::Log;
  const Eigen::Vector3d phi(0.3, -0.2, 0.1);
  const double round_trip_error = (Log(Exp(phi)) - phi).norm();

  // A one-block Ceres problem on the library's quaternion manifold: pull q to a target.
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  const Eigen::Quaterniond target = Exp(phi);
  ceres::Problem problem;
  problem.AddResidualBlock(new ceres::AutoDiffCostFunction<Residual, 3, 4>(new Residual(target)),
                           nullptr, q.coeffs().data());
  problem.SetManifold(q.coeffs().data(), new autocal::geometry::RightQuaternionManifold);
  ceres::Solver::Options options;
  options.function_tolerance = 1e-16;
  options.gradient_tolerance = 1e-16;
  options.parameter_tolerance = 1e-16;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  const double solve_error = autocal::geometry::AngularDistance(q, target);

  if (round_trip_error > 1e-12 || solve_error > 1e-9) {
    std::printf("autocal consumer: FAILED (round trip %g, solve %g)\n", round_trip_error,
                solve_error);
    return 1;
  }
  std::printf("autocal consumer: ok\n");
  return 0;
}
