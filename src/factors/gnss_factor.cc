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

GnssFactor::GnssFactor(const GnssMeasurement& measurement, GnssAxes axes)
    : p_W_A_(measurement.p_W_A),
      inv_sigma_(measurement.sigma_enu_m.cwiseInverse()),
      first_row_(FirstRow(axes)) {
  CheckMeasurement(measurement);
  set_num_residuals(NumRows(axes));
  *mutable_parameter_block_sizes() = {4, 3, 3};
}

bool GnssFactor::Evaluate(double const* const* parameters, double* residuals,
                          double** jacobians) const {
  const Eigen::Map<const Eigen::Quaterniond> q_W_I(parameters[0]);
  const Eigen::Map<const Eigen::Vector3d> p_W_I(parameters[1]);
  const Eigen::Map<const Eigen::Vector3d> p_I_A(parameters[2]);
  const Eigen::Matrix3d R = q_W_I.toRotationMatrix();
  const int rows = num_residuals();
  const Eigen::Vector3d r = inv_sigma_.asDiagonal() * (p_W_I + R * p_I_A - p_W_A_);  // Eq. F30
  Eigen::Map<Eigen::VectorXd>(residuals, rows) = r.segment(first_row_, rows);
  if (jacobians == nullptr) return true;
  using RowMajor3 = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
  // Eq. F31: d(R p)/d(dphi) = -R Hat(p) for R <- R Exp(dphi).
  if (jacobians[0] != nullptr) {
    const Eigen::Matrix3d j_tangent = inv_sigma_.asDiagonal() * (-R * geometry::Hat(p_I_A));
    const Eigen::Matrix<double, 3, 4, Eigen::RowMajor> j =
        geometry::LiftTangentJacobian<3>(j_tangent, parameters[0]);
    Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, 4, Eigen::RowMajor>>(jacobians[0], rows, 4) =
        j.middleRows(first_row_, rows);
  }
  if (jacobians[1] != nullptr) {
    const Eigen::Matrix3d j = inv_sigma_.asDiagonal();
    Eigen::Map<RowMajor3>(jacobians[1], rows, 3) = j.middleRows(first_row_, rows);
  }
  if (jacobians[2] != nullptr) {
    const Eigen::Matrix3d j = inv_sigma_.asDiagonal() * R;
    Eigen::Map<RowMajor3>(jacobians[2], rows, 3) = j.middleRows(first_row_, rows);
  }
  return true;
}

}  // namespace factors
}  // namespace autocal
