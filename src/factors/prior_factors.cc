#include "autocal/factors/prior_factors.h"

#include <Eigen/Cholesky>
#include <string>

#include "autocal/common/error.h"
#include "autocal/geometry/manifolds.h"
#include "autocal/geometry/so3.h"

namespace autocal {
namespace factors {

namespace {

void CheckSqrtInformation(const Eigen::MatrixXd& sqrt_information, int size, const char* what) {
  if (sqrt_information.rows() != size || sqrt_information.cols() != size) {
    throw Error(std::string(what) + ": square-root information must be " + std::to_string(size) +
                "x" + std::to_string(size) + ", got " + std::to_string(sqrt_information.rows()) +
                "x" + std::to_string(sqrt_information.cols()));
  }
  if (!sqrt_information.allFinite()) {
    throw Error(std::string(what) + ": square-root information is not finite");
  }
}

}  // namespace

Eigen::MatrixXd SqrtInformationFromSigmas(const Eigen::VectorXd& sigmas) {
  if (sigmas.size() == 0 || !sigmas.allFinite() || !(sigmas.array() > 0.0).all()) {
    throw Error("prior: every sigma must be positive and finite");
  }
  return sigmas.cwiseInverse().asDiagonal();
}

Eigen::MatrixXd SqrtInformationFromCovariance(const Eigen::MatrixXd& covariance) {
  if (covariance.rows() != covariance.cols() || covariance.rows() == 0 || !covariance.allFinite() ||
      !covariance.isApprox(covariance.transpose())) {
    throw Error("prior: covariance must be a finite symmetric square matrix");
  }
  const Eigen::LLT<Eigen::MatrixXd> llt(covariance);
  if (llt.info() != Eigen::Success) throw Error("prior: covariance is not positive definite");
  // Cov = L L^T  =>  Cov^-1 = L^-T L^-1, so U = L^-1.
  Eigen::MatrixXd sqrt_information =
      Eigen::MatrixXd::Identity(covariance.rows(), covariance.cols());
  llt.matrixL().solveInPlace(sqrt_information);
  return sqrt_information;
}

QuaternionPriorFactor::QuaternionPriorFactor(const Eigen::Quaterniond& q0,
                                             const Eigen::Matrix3d& sqrt_information)
    : q0_inv_(q0.normalized().conjugate()), sqrt_information_(sqrt_information) {
  if (!q0.coeffs().allFinite() || q0.norm() < 1e-6) throw Error("prior: invalid quaternion");
  CheckSqrtInformation(sqrt_information, 3, "quaternion prior");
}

bool QuaternionPriorFactor::Evaluate(double const* const* parameters, double* residuals,
                                     double** jacobians) const {
  const Eigen::Map<const Eigen::Quaterniond> q(parameters[0]);
  const Eigen::Vector3d e = geometry::Log(Eigen::Quaterniond(q0_inv_ * q));  // Eq. F40
  Eigen::Map<Eigen::Vector3d> r(residuals);
  r = sqrt_information_ * e;
  if (jacobians != nullptr && jacobians[0] != nullptr) {
    // Log(Exp(e) Exp(d)) = e + Jr^-1(e) d.
    const Eigen::Matrix3d j_tangent = sqrt_information_ * geometry::RightJacobianInverse(e);
    Eigen::Map<Eigen::Matrix<double, 3, 4, Eigen::RowMajor>> j(jacobians[0]);
    j = geometry::LiftTangentJacobian<3>(j_tangent, parameters[0]);
  }
  return true;
}

VectorPriorFactor::VectorPriorFactor(const Eigen::VectorXd& x0,
                                     const Eigen::MatrixXd& sqrt_information)
    : x0_(x0), sqrt_information_(sqrt_information) {
  if (x0.size() == 0 || !x0.allFinite()) throw Error("vector prior: value is empty or not finite");
  CheckSqrtInformation(sqrt_information, static_cast<int>(x0.size()), "vector prior");
  set_num_residuals(static_cast<int>(x0.size()));
  mutable_parameter_block_sizes()->push_back(static_cast<int>(x0.size()));
}

bool VectorPriorFactor::Evaluate(double const* const* parameters, double* residuals,
                                 double** jacobians) const {
  const int n = static_cast<int>(x0_.size());
  const Eigen::Map<const Eigen::VectorXd> x(parameters[0], n);
  Eigen::Map<Eigen::VectorXd> r(residuals, n);
  r = sqrt_information_ * (x - x0_);  // Eq. F41
  if (jacobians != nullptr && jacobians[0] != nullptr) {
    Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> j(
        jacobians[0], n, n);
    j = sqrt_information_;
  }
  return true;
}

StatePriorFactor::StatePriorFactor(const StatePrior& prior) : prior_(prior) {
  if (!prior.state.q_W_I.coeffs().allFinite() || !prior.state.p_W_I.allFinite() ||
      !prior.state.v_W_I.allFinite() || !prior.b_g.allFinite() || !prior.b_a.allFinite()) {
    throw Error("state prior: value is not finite");
  }
  // As QuaternionPriorFactor: a (near) zero quaternion is no rotation to normalize.
  if (prior.state.q_W_I.norm() < 1e-6) throw Error("state prior: invalid quaternion");
  prior_.state.q_W_I.normalize();
  CheckSqrtInformation(prior.sqrt_information, 15, "state prior");
}

bool StatePriorFactor::Evaluate(double const* const* parameters, double* residuals,
                                double** jacobians) const {
  const Eigen::Map<const Eigen::Quaterniond> q(parameters[0]);
  Eigen::Matrix<double, 15, 1> e;  // Eq. F42
  e.segment<3>(0) = geometry::Log(Eigen::Quaterniond(prior_.state.q_W_I.conjugate() * q));
  e.segment<3>(3) = Eigen::Map<const Eigen::Vector3d>(parameters[1]) - prior_.state.p_W_I;
  e.segment<3>(6) = Eigen::Map<const Eigen::Vector3d>(parameters[2]) - prior_.state.v_W_I;
  e.segment<3>(9) = Eigen::Map<const Eigen::Vector3d>(parameters[3]) - prior_.b_g;
  e.segment<3>(12) = Eigen::Map<const Eigen::Vector3d>(parameters[4]) - prior_.b_a;
  Eigen::Map<Eigen::Matrix<double, 15, 1>> r(residuals);
  r = prior_.sqrt_information * e;
  if (jacobians == nullptr) return true;
  if (jacobians[0] != nullptr) {
    const Eigen::Matrix<double, 15, 3> j_tangent =
        prior_.sqrt_information.leftCols<3>() * geometry::RightJacobianInverse(e.head<3>());
    Eigen::Map<Eigen::Matrix<double, 15, 4, Eigen::RowMajor>> j(jacobians[0]);
    j = geometry::LiftTangentJacobian<15>(j_tangent, parameters[0]);
  }
  for (int block = 1; block < 5; ++block) {
    if (jacobians[block] == nullptr) continue;
    Eigen::Map<Eigen::Matrix<double, 15, 3, Eigen::RowMajor>> j(jacobians[block]);
    j = prior_.sqrt_information.middleCols<3>(3 * block);
  }
  return true;
}

}  // namespace factors
}  // namespace autocal
