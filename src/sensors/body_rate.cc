#include "autocal/sensors/body_rate.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <string>

#include "autocal/common/error.h"
#include "autocal/common/time.h"
#include "autocal/sensors/imu_preintegration.h"

namespace autocal {
namespace sensors {

BodyRatePrior BodyRatePrior::Fit(const std::vector<GyroReading>& readings) {
  if (readings.size() < 2) {
    throw Error("BodyRatePrior: needs at least two gyro readings, got " +
                std::to_string(readings.size()));
  }
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double noise_sum = 0.0;
  for (size_t i = 0; i < readings.size(); ++i) {
    const GyroReading& r = readings[i];
    if (!r.rate_rad_s.allFinite() || !std::isfinite(r.noise_variance) || r.noise_variance < 0.0) {
      throw Error("BodyRatePrior: gyro reading " + std::to_string(i) +
                  " has a non-finite rate or a negative or non-finite noise variance");
    }
    sum += r.rate_rad_s;
    noise_sum += r.noise_variance;
  }
  const double n = static_cast<double>(readings.size());
  BodyRatePrior prior;
  prior.mean_rad_s_ = sum / n;
  Eigen::Matrix3d spread = Eigen::Matrix3d::Zero();
  for (const GyroReading& r : readings) {
    const Eigen::Vector3d d = r.rate_rad_s - prior.mean_rad_s_;
    spread += d * d.transpose();
  }
  spread /= n - 1.0;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(spread);
  const Eigen::Vector3d signal = (eig.eigenvalues().array() - noise_sum / n).max(0.0).matrix();
  prior.signal_covariance_ =
      eig.eigenvectors() * signal.asDiagonal() * eig.eigenvectors().transpose();
  return prior;
}

BodyRatePrior BodyRatePrior::FitToLog(const ImuSamples& imu, double period_s, double span_s,
                                      double sample_sigma) {
  if (!(period_s > 0.0) || !std::isfinite(period_s) || !(span_s >= 0.0) || !(sample_sigma >= 0.0) ||
      !std::isfinite(sample_sigma)) {
    throw Error("BodyRatePrior: the period must be positive, the span and sigma >= 0");
  }
  std::vector<GyroReading> readings;
  for (const GyroMean& mean : GyroAroundOverLog(imu, std::max<int64_t>(1, SecondsToNs(period_s)),
                                                SecondsToNs(0.5 * span_s))) {
    readings.push_back({mean.rate_rad_s, sample_sigma * sample_sigma / std::max(1, mean.samples)});
  }
  return Fit(readings);
}

BodyRate BodyRatePrior::Condition(const GyroReading& reading) const {
  if (!(reading.noise_variance > 0.0)) return {reading.rate_rad_s, Eigen::Matrix3d::Zero()};
  const Eigen::Matrix3d gain =
      signal_covariance_ *
      (signal_covariance_ + reading.noise_variance * Eigen::Matrix3d::Identity()).inverse();
  BodyRate out;
  out.rate_rad_s = mean_rad_s_ + gain * (reading.rate_rad_s - mean_rad_s_);
  const Eigen::Matrix3d p = reading.noise_variance * gain;
  out.covariance = 0.5 * (p + p.transpose());
  return out;
}

}  // namespace sensors
}  // namespace autocal
