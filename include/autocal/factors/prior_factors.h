#pragma once

// Priors (docs/factors.md, "Priors"): tie a calibration block or a keyframe state to a
// value with a given uncertainty, e.g. a CAD lever arm or the first state of a window.
//   quaternion:  r = U Log(q0^-1 q)                         Eq. F40 (right tangent)
//   vector:      r = U (x - x0)                             Eq. F41 (scalars are size 1)
//   state:       r = U [Log(q0^-1 q); p - p0; v - v0; b_g - b_g0; b_a - b_a0]   Eq. F42
// U is a square root of the information (U^T U = Cov^-1); SqrtInformationFromSigmas and
// SqrtInformationFromCovariance build it.

#include <ceres/ceres.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "autocal/sensors/imu_preintegration.h"

namespace autocal {
namespace factors {

// diag(1 / sigma); throws autocal::Error unless every sigma is positive and finite.
Eigen::MatrixXd SqrtInformationFromSigmas(const Eigen::VectorXd& sigmas);
// The inverse Cholesky factor of a symmetric positive-definite covariance; throws
// autocal::Error otherwise.
Eigen::MatrixXd SqrtInformationFromCovariance(const Eigen::MatrixXd& covariance);

// Parameter block: a quaternion (4, RightQuaternionManifold).
class QuaternionPriorFactor final : public ceres::SizedCostFunction<3, 4> {
 public:
  QuaternionPriorFactor(const Eigen::Quaterniond& q0, const Eigen::Matrix3d& sqrt_information);
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

 private:
  Eigen::Quaterniond q0_inv_;
  Eigen::Matrix3d sqrt_information_;
};

// Parameter block: a vector of x0.size() entries (a scalar block has size 1).
class VectorPriorFactor final : public ceres::CostFunction {
 public:
  VectorPriorFactor(const Eigen::VectorXd& x0, const Eigen::MatrixXd& sqrt_information);
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

 private:
  Eigen::VectorXd x0_;
  Eigen::MatrixXd sqrt_information_;
};

struct StatePrior {
  sensors::NavStated state;
  Eigen::Vector3d b_g = Eigen::Vector3d::Zero();
  Eigen::Vector3d b_a = Eigen::Vector3d::Zero();
  // 15x15, ordered like the residual [dphi, dp, dv, db_g, db_a].
  Eigen::Matrix<double, 15, 15> sqrt_information = Eigen::Matrix<double, 15, 15>::Identity();
};

// Parameter blocks: q_W_I (4, RightQuaternionManifold), p_W_I (3), v_W_I (3), b_g (3), b_a (3).
class StatePriorFactor final : public ceres::SizedCostFunction<15, 4, 3, 3, 3, 3> {
 public:
  explicit StatePriorFactor(const StatePrior& prior);
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

 private:
  StatePrior prior_;
};

}  // namespace factors
}  // namespace autocal
