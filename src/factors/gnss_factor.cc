#include "autocal/factors/gnss_factor.h"

#include <string>

#include "autocal/common/error.h"
#include "autocal/geometry/manifolds.h"

namespace autocal {
namespace factors {

namespace {

void CheckMeasurement(const GnssMeasurement& m) {
  if (!m.p_W_A.allFinite()) throw Error("GNSS factor: antenna position is not finite");
  if (!m.sigma_enu_m.allFinite() || !(m.sigma_enu_m.array() > 0.0).all()) {
    throw Error("GNSS factor: standard deviations must be positive, got (" +
                std::to_string(m.sigma_enu_m.x()) + ", " + std::to_string(m.sigma_enu_m.y()) +
                ", " + std::to_string(m.sigma_enu_m.z()) + ") m");
  }
}

}  // namespace

GnssMeasurement GnssMeasurement::FromFix(const sensors::GnssFix& fix,
                                         const sensors::EnuConverter& converter) {
  GnssMeasurement m;
  m.p_W_A = converter.ToEnu(fix);
  m.sigma_enu_m = fix.std_enu_m;
  CheckMeasurement(m);
  return m;
}

GnssFactor::GnssFactor(const GnssMeasurement& measurement)
    : p_W_A_(measurement.p_W_A), inv_sigma_(measurement.sigma_enu_m.cwiseInverse()) {
  CheckMeasurement(measurement);
}

bool GnssFactor::Evaluate(double const* const* parameters, double* residuals,
                          double** jacobians) const {
  const Eigen::Map<const Eigen::Quaterniond> q_W_I(parameters[0]);
  const Eigen::Map<const Eigen::Vector3d> p_W_I(parameters[1]);
  const Eigen::Map<const Eigen::Vector3d> p_I_A(parameters[2]);
  const Eigen::Matrix3d R = q_W_I.toRotationMatrix();
  Eigen::Map<Eigen::Vector3d> r(residuals);
  r = inv_sigma_.asDiagonal() * (p_W_I + R * p_I_A - p_W_A_);  // Eq. F30
  if (jacobians == nullptr) return true;
  // Eq. F31: d(R p)/d(dphi) = -R Hat(p) for R <- R Exp(dphi).
  if (jacobians[0] != nullptr) {
    const Eigen::Matrix3d j_tangent = inv_sigma_.asDiagonal() * (-R * geometry::Hat(p_I_A));
    Eigen::Map<Eigen::Matrix<double, 3, 4, Eigen::RowMajor>> j(jacobians[0]);
    j = geometry::LiftTangentJacobian<3>(j_tangent, parameters[0]);
  }
  if (jacobians[1] != nullptr) {
    Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> j(jacobians[1]);
    j = inv_sigma_.asDiagonal();
  }
  if (jacobians[2] != nullptr) {
    Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> j(jacobians[2]);
    j = inv_sigma_.asDiagonal() * R;
  }
  return true;
}

}  // namespace factors
}  // namespace autocal
