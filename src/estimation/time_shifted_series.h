#pragma once

// A sensor's samples read at an IMU-clock instant through the sensor's time offset
// (docs/keyframe_factors.md, Eq. K9). With the project's sign, t_imu = t_sensor + offset, the
// sample the sensor would have stamped at IMU time t_k is the one at t_k - offset on its own
// clock: x(t_k - offset), linearly interpolated (Eq. K1) between the samples bracketing that
// instant. The value is templated on the scalar so that a ceres::Jet offset carries
//   dx/d(offset) = -x'(t_k - offset),
// x' the slope of a least-squares line through the samples within kSlopeHalfWidthS (at least
// two on each side) of the bracketing segment's middle (Eq. K9b): the factors that read a
// series this way estimate the offset in the solve. The segment's own slope (x1 - x0) /
// (t1 - t0) would carry the two samples' noise into the Jacobian, correlated with the residual
// it multiplies: errors in variables, which biased a 100 Hz wheel clock by 4.4 ms at a stated
// sigma of 0.24 ms (with the line: 1.2 ms at 0.74 ms). The bracket is chosen on the offset's value
// at each evaluation.

#include <ceres/jet.h>

#include <Eigen/Core>
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/time.h"

namespace autocal {
namespace estimation {
namespace internal {

inline double ScalarPart(double x) { return x; }
template <typename T, int N>
double ScalarPart(const ceres::Jet<T, N>& x) {
  return x.a;
}

// Half the span of the line that gives a segment's slope: a vehicle's speed, yaw rate and
// position change over seconds, so a line over one second follows them while averaging the
// samples' noise (over 0.2 s a 100 Hz wheel clock estimated with the GNSS clock still ended
// 20 ms off on the simulated urban drive; over 1 s, 3.9 ms at sigma 0.97 ms).
constexpr double kSlopeHalfWidthS = 0.5;

template <int N>
class TimeShiftedSeries {
 public:
  using Value = Eigen::Matrix<double, N, 1>;

  TimeShiftedSeries() = default;
  // Stamps on the sensor's clock, strictly increasing; one value per stamp. Throws
  // autocal::Error naming `what` otherwise.
  TimeShiftedSeries(const std::vector<int64_t>& t_ns, std::vector<Value> values,
                    const std::string& what)
      : values_(std::move(values)) {
    if (t_ns.size() != values_.size() || t_ns.size() < 2) {
      throw Error(what + ": a time-shifted series needs at least two samples, one value per stamp");
    }
    t0_ns_ = t_ns.front();
    t_s_.reserve(t_ns.size());
    for (size_t i = 0; i < t_ns.size(); ++i) {
      if (i > 0 && t_ns[i] <= t_ns[i - 1]) {
        throw Error(what + " stamps must increase: sample " + std::to_string(i) + " at " +
                    std::to_string(t_ns[i]) + " ns follows " + std::to_string(t_ns[i - 1]) + " ns");
      }
      t_s_.push_back(NsToSeconds(t_ns[i] - t0_ns_));
    }
    slopes_.resize(t_s_.size());
    for (size_t i = 1; i < t_s_.size(); ++i) slopes_[i] = LineSlope(i);
  }

  size_t size() const { return t_s_.size(); }

  // The largest spacing of the two samples around the sensor-clock instant t_k - offset_s
  // (0 for an instant on a sample; infinity outside the samples): the caller's gap test.
  double BracketSpanS(int64_t t_imu_ns, double offset_s) const {
    const double t = QueryS(t_imu_ns, offset_s);
    if (t < t_s_.front() || t > t_s_.back()) return std::numeric_limits<double>::infinity();
    const size_t i = SecondIndex(t);
    if (t_s_[i] == t) return 0.0;
    return t_s_[i] - t_s_[i - 1];
  }

  // x(t_imu - offset). Outside the samples the nearest end sample is returned (no slope).
  template <typename T>
  Eigen::Matrix<T, N, 1> At(int64_t t_imu_ns, const T& offset_s) const {
    const T t = T(NsToSeconds(t_imu_ns - t0_ns_)) - offset_s;
    const double t_value = ScalarPart(t);
    if (!(t_value > t_s_.front())) return values_.front().template cast<T>();
    if (!(t_value < t_s_.back())) return values_.back().template cast<T>();
    const size_t i = SecondIndex(t_value);
    const double s = (t_value - t_s_[i - 1]) / (t_s_[i] - t_s_[i - 1]);
    const Value x = values_[i - 1] * (1.0 - s) + values_[i] * s;
    // t - t_value is zero with the offset's derivative: the line's slope carries it.
    return (x.template cast<T>() + slopes_[i].template cast<T>() * (t - T(t_value))).eval();
  }

 private:
  double QueryS(int64_t t_imu_ns, double offset_s) const {
    return NsToSeconds(t_imu_ns - t0_ns_) - offset_s;
  }
  // The first sample at or after t (t inside the samples, after the first one).
  size_t SecondIndex(double t) const {
    const auto it = std::lower_bound(t_s_.begin(), t_s_.end(), t);
    return std::max<size_t>(1, static_cast<size_t>(it - t_s_.begin()));
  }

  // The least-squares slope through the samples within kSlopeHalfWidthS of the middle of
  // segment (i - 1, i), at least two on each side where the series has them.
  Value LineSlope(size_t i) const {
    const double middle = 0.5 * (t_s_[i - 1] + t_s_[i]);
    size_t first = i - 1, last = i;
    while (first > 0 && (i - first < 2 || middle - t_s_[first - 1] <= kSlopeHalfWidthS)) --first;
    while (last + 1 < t_s_.size() &&
           (last + 1 - i < 2 || t_s_[last + 1] - middle <= kSlopeHalfWidthS)) {
      ++last;
    }
    double t_mean = 0.0;
    Value x_mean = Value::Zero();
    for (size_t k = first; k <= last; ++k) {
      t_mean += t_s_[k];
      x_mean += values_[k];
    }
    const double n = static_cast<double>(last - first + 1);
    t_mean /= n;
    x_mean /= n;
    double stt = 0.0;
    Value stx = Value::Zero();
    for (size_t k = first; k <= last; ++k) {
      stt += (t_s_[k] - t_mean) * (t_s_[k] - t_mean);
      stx += (t_s_[k] - t_mean) * (values_[k] - x_mean);
    }
    return stx / stt;
  }

  int64_t t0_ns_ = 0;
  std::vector<double> t_s_;  // seconds since t0_ns_
  std::vector<Value> values_;
  std::vector<Value> slopes_;  // per segment (i - 1, i), at i; slopes_[0] unused
};

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
