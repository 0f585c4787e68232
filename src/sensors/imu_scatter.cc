#include "autocal/sensors/imu_scatter.h"

#include <cmath>
#include <string>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/time.h"
#include "autocal/sensors/sample_timing.h"
#include "common/order_statistics.h"

namespace autocal {
namespace sensors {
namespace {

// Eq. N1 for one axis of one sensor: `axis` picks the value of a sample.
template <typename Axis>
double AxisDensity(const ImuSamples& imu, double rate_hz, Axis axis) {
  std::vector<double> differences;
  differences.reserve(imu.size() - 2);
  for (size_t k = 1; k + 1 < imu.size(); ++k) {
    differences.push_back(axis(imu[k + 1]) - 2.0 * axis(imu[k]) + axis(imu[k - 1]));
  }
  return internal::MadSigma(differences) / std::sqrt(6.0) / std::sqrt(rate_hz);
}

double Rms(const Eigen::Vector3d& v) { return std::sqrt(v.squaredNorm() / 3.0); }

}  // namespace

double ImuScatter::gyroscope_noise_density() const { return Rms(gyro_density); }
double ImuScatter::accelerometer_noise_density() const { return Rms(accel_density); }

ImuScatter MeasureImuScatter(const ImuSamples& imu) {
  if (imu.size() < 3) {
    throw Error("MeasureImuScatter: need at least three IMU samples, got " +
                std::to_string(imu.size()));
  }
  std::vector<int64_t> stamps_ns;
  stamps_ns.reserve(imu.size());
  for (size_t k = 0; k < imu.size(); ++k) {
    if (k > 0 && imu[k].t_ns <= imu[k - 1].t_ns) {
      throw Error("MeasureImuScatter: IMU sample " + std::to_string(k) +
                  " does not follow its predecessor");
    }
    stamps_ns.push_back(imu[k].t_ns);
  }
  ImuScatter s;
  s.differences = imu.size() - 2;
  // The rate the samples were taken at: a driver that stamps them in bursts leaves the median
  // interval at the burst's spacing (docs/keyframe_factors.md, "Limits from the log's timing").
  s.rate_hz = MeasureTiming(stamps_ns, "MeasureImuScatter: IMU").rate_hz();
  for (int i = 0; i < 3; ++i) {
    s.gyro_density(i) =
        AxisDensity(imu, s.rate_hz, [i](const ImuSample& x) { return x.gyro_rad_s(i); });
    s.accel_density(i) =
        AxisDensity(imu, s.rate_hz, [i](const ImuSample& x) { return x.accel_m_s2(i); });
  }
  return s;
}

}  // namespace sensors
}  // namespace autocal
