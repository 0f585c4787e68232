#include "autocal/estimation/planar_rotation_rows.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <optional>
#include <string>

#include "autocal/common/error.h"
#include "autocal/common/time.h"
#include "autocal/factors/planar_rotation_factor.h"
#include "autocal/geometry/manifolds.h"
#include "autocal/sensors/imu_preintegration.h"
#include "common/correlation.h"
#include "common/order_statistics.h"
#include "estimation/keyframe_interpolation.h"

namespace autocal {
namespace estimation {
namespace {

// The gyro reading at t_k: the mean over span_ns around it, or the sample interpolated there.
std::optional<Eigen::Vector3d> GyroAt(const sensors::ImuSamples& imu, int64_t t_ns,
                                      int64_t max_gap_ns, int64_t span_ns) {
  if (!internal::FindBracket(imu, t_ns, max_gap_ns)) return std::nullopt;
  return sensors::GyroAround(imu, t_ns, span_ns / 2).rate_rad_s;
}

}  // namespace

PlanarRotationSpread MeasurePlanarRotationSpread(const std::vector<Eigen::Vector3d>& rates_V) {
  const size_t n = rates_V.size();
  if (n < 10) {
    throw Error("planar-rotation rows: " + std::to_string(n) +
                " keyframe body rates are too few to measure their spread (10 or more)");
  }
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& w : rates_V) {
    if (!w.allFinite()) throw Error("planar-rotation rows: a body rate is not finite");
    mean += w;
  }
  mean /= static_cast<double>(n);
  double zz = 0.0;
  Eigen::Vector2d xz = Eigen::Vector2d::Zero();
  for (const Eigen::Vector3d& w : rates_V) {
    const Eigen::Vector3d d = w - mean;
    zz += d.z() * d.z();
    xz += d.z() * d.head<2>();
  }
  PlanarRotationSpread spread;
  spread.samples = static_cast<int>(n);
  spread.slope = zz > 0.0 ? Eigen::Vector2d(xz / zz) : Eigen::Vector2d::Zero();
  for (int axis = 0; axis < 2; ++axis) {
    std::vector<double> e(n);
    for (size_t k = 0; k < n; ++k) {
      const Eigen::Vector3d d = rates_V[k] - mean;
      e[k] = d(axis) - spread.slope(axis) * d.z();
    }
    spread.correlation_scale(axis) = autocal::internal::CorrelationScale(e);
    spread.sigma_rad_s(axis) = autocal::internal::MadSigma(e);
  }
  return spread;
}

double PlanarRotationSpread::RowSigmaRadS() const {
  return std::max(sigma_rad_s.cwiseProduct(correlation_scale).norm() / std::sqrt(2.0), 1e-6);
}

PlanarRotationSpread MeasurePlanarRotationSpreadOfLog(const sensors::ImuSamples& imu,
                                                      const Eigen::Quaterniond& q_I_V,
                                                      double period_s, double gyro_mean_span_s) {
  if (!(period_s > 0.0) || !std::isfinite(period_s)) {
    throw Error("planar-rotation rows: the keyframe period must be positive");
  }
  const Eigen::Matrix3d R_V_I = q_I_V.toRotationMatrix().transpose();
  std::vector<Eigen::Vector3d> rates_V;
  for (const sensors::GyroMean& mean : sensors::GyroAroundOverLog(
           imu, std::max<int64_t>(1, SecondsToNs(period_s)), SecondsToNs(gyro_mean_span_s) / 2)) {
    rates_V.push_back(R_V_I * mean.rate_rad_s);
  }
  return MeasurePlanarRotationSpread(rates_V);
}

PlanarRotationRows AddPlanarRotationFactors(ceres::Problem* problem, const sensors::ImuSamples& imu,
                                            std::vector<Keyframe>* keyframes,
                                            sensors::Calibration* calibration,
                                            const PlanarRotationOptions& options) {
  if (!(options.sigma_rad_s >= 0.0) || !std::isfinite(options.sigma_rad_s) ||
      !(options.gyro_mean_span_s >= 0.0)) {
    throw Error("planar-rotation rows: sigma_rad_s and gyro_mean_span_s must be finite and >= 0");
  }
  const double* q_I_V = calibration->q_I_V.coeffs().data();
  if (!problem->HasParameterBlock(q_I_V) || dynamic_cast<const geometry::RightQuaternionManifold*>(
                                                problem->GetManifold(q_I_V)) == nullptr) {
    throw Error("planar-rotation rows: q_I_V must be in the problem with RightQuaternionManifold");
  }
  const int64_t max_gap_ns =
      internal::GapNsOrFromStamps(options.max_imu_gap_s, imu, "max_imu_gap_s");
  const int64_t span_ns = SecondsToNs(options.gyro_mean_span_s);
  const Eigen::Matrix3d R_V_I = calibration->q_I_V.toRotationMatrix().transpose();
  std::vector<std::optional<Eigen::Vector3d>> readings(keyframes->size());
  std::vector<Eigen::Vector3d> rates_V;
  for (size_t k = 0; k < keyframes->size(); ++k) {
    const Keyframe& kf = (*keyframes)[k];
    readings[k] = GyroAt(imu, kf.t_ns, max_gap_ns, span_ns);
    if (readings[k]) rates_V.push_back(R_V_I * (*readings[k] - kf.b_g));
  }
  PlanarRotationRows rows;
  if (options.sigma_rad_s > 0.0) {
    rows.sigma_rad_s = options.sigma_rad_s;
  } else {
    rows.spread = MeasurePlanarRotationSpread(rates_V);
    rows.sigma_rad_s = rows.spread.RowSigmaRadS();
  }
  std::unique_ptr<ceres::LossFunction> unused_loss(factors::MakeLossFunction(options.loss));
  ceres::LossFunction* loss = unused_loss.get();
  for (size_t k = 0; k < keyframes->size(); ++k) {
    if (!readings[k]) continue;
    factors::PlanarRotationMeasurement m;
    m.gyro_rad_s = *readings[k];
    m.sigma_rad_s = rows.sigma_rad_s;
    problem->AddResidualBlock(factors::PlanarRotationFactor::Create(m), loss,
                              (*keyframes)[k].b_g.data(), calibration->q_I_V.coeffs().data());
    unused_loss.release();
    ++rows.added;
  }
  return rows;
}

}  // namespace estimation
}  // namespace autocal
