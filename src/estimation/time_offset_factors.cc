#include "estimation/time_offset_factors.h"

#include <algorithm>
#include <cstddef>

#include "autocal/common/error.h"

namespace autocal {
namespace estimation {
namespace internal {

std::optional<ImuAroundKeyframe> ImuAround(const sensors::ImuSamples& imu, int64_t t_ns,
                                           double gravity_m_s2, int64_t max_gap_ns) {
  if (imu.size() < 2) throw Error("ImuAround: the IMU log holds fewer than two samples");
  if (t_ns < imu.front().t_ns || t_ns > imu.back().t_ns) return std::nullopt;
  const int64_t half_ns = SecondsToNs(kImuLineHalfWidthS);
  const auto later = [](const sensors::ImuSample& a, int64_t t) { return a.t_ns < t; };
  const auto at = std::lower_bound(imu.begin(), imu.end(), t_ns, later);
  const auto first_within = std::lower_bound(imu.begin(), imu.end(), t_ns - half_ns, later);
  const auto past_within = std::lower_bound(imu.begin(), imu.end(), t_ns + half_ns + 1, later);
  const auto first = std::min(first_within, at - std::min<std::ptrdiff_t>(2, at - imu.begin()));
  const auto past = std::max(past_within, at + std::min<std::ptrdiff_t>(2, imu.end() - at));
  for (auto it = first + 1; it != past; ++it) {
    if (it->t_ns - (it - 1)->t_ns > max_gap_ns) return std::nullopt;
  }
  // Least squares in tau = t - t_ns: x(tau) = x0 + slope tau.
  double n = 0.0, mean_tau = 0.0;
  Eigen::Vector3d mean_gyro = Eigen::Vector3d::Zero(), mean_accel = Eigen::Vector3d::Zero();
  for (auto it = first; it != past; ++it) {
    n += 1.0;
    mean_tau += NsToSeconds(it->t_ns - t_ns);
    mean_gyro += it->gyro_rad_s;
    mean_accel += it->accel_m_s2;
  }
  mean_tau /= n;
  mean_gyro /= n;
  mean_accel /= n;
  double stt = 0.0;
  Eigen::Vector3d stg = Eigen::Vector3d::Zero(), sta = Eigen::Vector3d::Zero();
  for (auto it = first; it != past; ++it) {
    const double d = NsToSeconds(it->t_ns - t_ns) - mean_tau;
    stt += d * d;
    stg += d * (it->gyro_rad_s - mean_gyro);
    sta += d * (it->accel_m_s2 - mean_accel);
  }
  ImuAroundKeyframe out;
  out.gyro_slope_rad_s2 = stg / stt;
  out.gyro_rad_s = mean_gyro - out.gyro_slope_rad_s2 * mean_tau;
  out.accel_m_s2 = mean_accel - (sta / stt) * mean_tau;
  out.g_W = Eigen::Vector3d(0.0, 0.0, -gravity_m_s2);
  return out;
}

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
