#pragma once

// The body rate behind a noisy gyro reading (docs/keyframe_factors.md, Eq. K14). A factor
// that multiplies a rate into an unknown, like the wheel rows' w x p_I_V, must not take the
// reading itself: its noise then looks like excitation, and an axis the drive never turns
// about (a ground vehicle's roll and pitch) seems to determine the lever arm and the mount
// tilt, more firmly the noisier the gyro, while the estimate shrinks towards zero. Taken
// instead is the rate's expectation given the reading, with the covariance left over:
//   C = Cov(w) - sigma^2 I  (the rates' spread over the log less the noise; clamped to >= 0)
//   E[w_true | w] = mu + K (w - mu),   K = C (C + sigma^2 I)^-1,   P = sigma^2 K.
// An axis with no excitation (C = 0) gets the log's mean and its noise as covariance; an
// excited one (C >> sigma^2) the reading and nearly no extra covariance.

#include <Eigen/Core>
#include <vector>

#include "autocal/sensors/measurements.h"

namespace autocal {
namespace sensors {

// One gyro reading (a mean over a span) and the variance of its white noise per axis.
struct GyroReading {
  Eigen::Vector3d rate_rad_s = Eigen::Vector3d::Zero();
  double noise_variance = 0.0;  // (rad/s)^2, isotropic
};

// The rate given a reading: its expectation and the covariance of the true rate about it.
struct BodyRate {
  Eigen::Vector3d rate_rad_s = Eigen::Vector3d::Zero();
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
};

class BodyRatePrior {
 public:
  // The mean and the signal covariance C of the readings (Eq. K14). Throws autocal::Error for
  // fewer than two readings or a non-finite or negative value.
  static BodyRatePrior Fit(const std::vector<GyroReading>& readings);

  // E[w_true | reading] and P (Eq. K14). A reading without noise is returned as it is.
  BodyRate Condition(const GyroReading& reading) const;

  // Fit to a whole log: the gyro averaged over span_s around every period_s from the first
  // sample to the last, each mean's noise variance sample_sigma^2 / n for n samples averaged
  // (sample_sigma: the 1-sigma of one sample, density * sqrt(rate)). Throws as Fit, and for a
  // non-positive period or a negative span or sigma.
  static BodyRatePrior FitToLog(const ImuSamples& imu, double period_s, double span_s,
                                double sample_sigma);

  const Eigen::Vector3d& mean_rad_s() const { return mean_rad_s_; }
  const Eigen::Matrix3d& signal_covariance() const { return signal_covariance_; }

 private:
  Eigen::Vector3d mean_rad_s_ = Eigen::Vector3d::Zero();
  Eigen::Matrix3d signal_covariance_ = Eigen::Matrix3d::Zero();
};

}  // namespace sensors
}  // namespace autocal
