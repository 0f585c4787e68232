#pragma once

// Measurements interpolated to keyframe instants (docs/keyframe_factors.md, Eq. K1), shared by
// the keyframe factors, the GNSS alignment of keyframes and their placement.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <type_traits>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/time.h"
#include "autocal/estimation/keyframe.h"
#include "autocal/factors/gnss_factor.h"
#include "autocal/sensors/gnss_enu.h"
#include "autocal/sensors/measurements.h"
#include "autocal/sensors/sample_timing.h"

namespace autocal {
namespace estimation {
namespace internal {

// The samples bracketing an instant and the weight of the later one (Eq. K1):
// x(t) = (1 - s) x[first] + s x[second].
struct Bracket {
  size_t first = 0;
  size_t second = 0;
  double s = 0.0;
};

template <typename Sample>
void CheckIncreasing(const std::vector<Sample>& samples, const std::string& what) {
  for (size_t i = 1; i < samples.size(); ++i) {
    if (samples[i].t_ns <= samples[i - 1].t_ns) {
      throw Error(what + " stamps must increase: sample " + std::to_string(i) + " at " +
                  std::to_string(samples[i].t_ns) + " ns follows " +
                  std::to_string(samples[i - 1].t_ns) + " ns");
    }
  }
}

// A sample exactly at t_ns is used alone; otherwise the two around it, unless they are more
// than max_gap_ns apart or t_ns lies outside the samples.
template <typename Sample>
std::optional<Bracket> FindBracket(const std::vector<Sample>& samples, int64_t t_ns,
                                   int64_t max_gap_ns) {
  const auto it = std::lower_bound(samples.begin(), samples.end(), t_ns,
                                   [](const Sample& a, int64_t t) { return a.t_ns < t; });
  if (it == samples.end()) return std::nullopt;
  const size_t second = static_cast<size_t>(it - samples.begin());
  if (it->t_ns == t_ns) return Bracket{second, second, 0.0};
  if (second == 0) return std::nullopt;
  const size_t first = second - 1;
  const int64_t gap_ns = samples[second].t_ns - samples[first].t_ns;
  if (gap_ns > max_gap_ns) return std::nullopt;
  return Bracket{first, second,
                 static_cast<double>(t_ns - samples[first].t_ns) / static_cast<double>(gap_ns)};
}

// A mean of samples' values and the sum of the squared weights it gives them: for independent
// samples of noise sigma the mean's noise is sigma sqrt(weight_squares).
template <typename Value>
struct WeightedMean {
  Value value;
  double weight_squares = 1.0;
};

// The time mean over [a_ns, b_ns] of the samples' values joined by straight lines (Eq. K13b):
// each segment between two samples, clipped to the span, contributes its length times the
// mean of its ends. a_ns == b_ns gives the instant's value (Eq. K1). nullopt unless samples
// bracket both ends of the span and no segment it touches is longer than max_gap_ns.
template <typename Sample, typename ValueOf>
auto MeanOverSpan(const std::vector<Sample>& samples, int64_t a_ns, int64_t b_ns,
                  int64_t max_gap_ns, ValueOf value_of)
    -> std::optional<WeightedMean<std::decay_t<decltype(value_of(samples.front()))>>> {
  using Value = std::decay_t<decltype(value_of(samples.front()))>;
  const std::optional<Bracket> start = FindBracket(samples, a_ns, max_gap_ns);
  if (!start || b_ns < a_ns) return std::nullopt;
  if (a_ns == b_ns) {
    const double s = start->s;
    return WeightedMean<Value>{
        (1.0 - s) * value_of(samples[start->first]) + s * value_of(samples[start->second]),
        start->first == start->second ? 1.0 : (1.0 - s) * (1.0 - s) + s * s};
  }
  const double span_ns = static_cast<double>(b_ns - a_ns);
  std::vector<double> weights(1, 0.0);  // of samples start->first, start->first + 1, ...
  size_t i = start->first;
  for (; i + 1 < samples.size() && samples[i].t_ns < b_ns; ++i) {
    const int64_t t0 = samples[i].t_ns;
    const int64_t t1 = samples[i + 1].t_ns;
    if (t1 - t0 > max_gap_ns) return std::nullopt;
    const double length = static_cast<double>(t1 - t0);
    const double u = static_cast<double>(std::max(a_ns, t0) - t0) / length;
    const double v = static_cast<double>(std::min(b_ns, t1) - t0) / length;
    const double share = (v - u) * length / span_ns;
    const double later = 0.5 * (u + v);  // the later sample's weight within the segment
    weights.back() += share * (1.0 - later);
    weights.push_back(share * later);
  }
  if (samples[i].t_ns < b_ns) return std::nullopt;
  WeightedMean<Value> mean{0.0 * value_of(samples[start->first]), 0.0};
  for (size_t j = 0; j < weights.size(); ++j) {
    mean.value = mean.value + weights[j] * value_of(samples[start->first + j]);
    mean.weight_squares += weights[j] * weights[j];
  }
  return mean;
}

// A sample's stamp, or the stamp itself.
inline int64_t StampOf(int64_t t_ns) { return t_ns; }
template <typename Sample>
int64_t StampOf(const Sample& sample) {
  return sample.t_ns;
}

// The sample each keyframe takes when the sensor's clock is offset_ns from the IMU's
// (docs/keyframe_factors.md, Eq. K17): the one nearest the sensor-clock instant t_k - offset,
// kept when it was taken no farther than max_distance_ns from t_k and no other keyframe lies
// nearer its IMU-clock instant t_j + offset, so that no sample serves two keyframes. Ties go
// forward in time: a keyframe midway between two samples takes the later one, and a sample
// midway between two keyframes serves the earlier, so that samples half a period off keyframes
// as dense as they are each serve one (were the earlier sample taken, the earlier keyframe
// would win it back, and every keyframe would go without). The first
// and the last keyframe take no sample beyond half their interval to their neighbour: a state
// is carried no farther than that (Eq. K16). Samples (or their stamps) and keyframes strictly
// increasing in time.
template <typename Sample>
std::vector<std::optional<size_t>> NearestSamples(const std::vector<Sample>& samples,
                                                  const std::vector<Keyframe>& keyframes,
                                                  int64_t offset_ns, int64_t max_distance_ns) {
  std::vector<std::optional<size_t>> paired(keyframes.size());
  if (samples.empty()) return paired;
  const auto distance = [](int64_t a, int64_t b) { return a > b ? a - b : b - a; };
  for (size_t k = 0; k < keyframes.size(); ++k) {
    const int64_t t_k = keyframes[k].t_ns;
    const auto it = std::lower_bound(samples.begin(), samples.end(), t_k - offset_ns,
                                     [](const Sample& a, int64_t t) { return StampOf(a) < t; });
    size_t j = static_cast<size_t>(it - samples.begin());
    if (j == samples.size() || (j > 0 && distance(StampOf(samples[j - 1]) + offset_ns, t_k) <
                                             distance(StampOf(samples[j]) + offset_ns, t_k))) {
      --j;
    }
    const int64_t t_imu = StampOf(samples[j]) + offset_ns;
    const int64_t d = distance(t_imu, t_k);
    if (d > max_distance_ns) continue;
    // The neighbours; beyond the first and the last keyframe, their interval mirrored.
    const size_t n = keyframes.size();
    if (n > 1) {
      const int64_t before = k > 0 ? keyframes[k - 1].t_ns : 2 * t_k - keyframes[1].t_ns;
      const int64_t after = k + 1 < n ? keyframes[k + 1].t_ns : 2 * t_k - keyframes[n - 2].t_ns;
      if (distance(t_imu, before) <= d || distance(t_imu, after) < d) continue;
    }
    paired[k] = j;
  }
  return paired;
}

// The keyframe each sample serves when every sample serves its nearest keyframe (the GNSS fixes
// without a clock offset when keyframes would share them, Eq. K17): the keyframe nearest the
// sample's stamp, kept within max_distance_ns and, beyond the first and the last keyframe, no
// farther than half their interval to their neighbour (a state is carried no farther, Eq. K16).
// A sample midway between two keyframes serves the later. Unlike NearestSamples a keyframe may
// take several samples, so that samples denser than the keyframes all count, each once.
// Samples (or their stamps) and keyframes strictly increasing in time.
template <typename Sample>
std::vector<std::optional<size_t>> NearestKeyframes(const std::vector<Sample>& samples,
                                                    const std::vector<Keyframe>& keyframes,
                                                    int64_t max_distance_ns) {
  std::vector<std::optional<size_t>> serves(samples.size());
  const size_t n = keyframes.size();
  if (n == 0) return serves;
  const auto distance = [](int64_t a, int64_t b) { return a > b ? a - b : b - a; };
  for (size_t j = 0; j < samples.size(); ++j) {
    const int64_t t = StampOf(samples[j]);
    const auto it = std::lower_bound(keyframes.begin(), keyframes.end(), t,
                                     [](const Keyframe& kf, int64_t s) { return kf.t_ns < s; });
    size_t k = static_cast<size_t>(it - keyframes.begin());
    if (k == n || (k > 0 && distance(keyframes[k - 1].t_ns, t) < distance(keyframes[k].t_ns, t))) {
      --k;
    }
    const int64_t d = distance(keyframes[k].t_ns, t);
    if (d > max_distance_ns) continue;
    if (n > 1 &&
        ((k == 0 && distance(2 * keyframes[0].t_ns - keyframes[1].t_ns, t) < d) ||
         (k + 1 == n && distance(2 * keyframes[k].t_ns - keyframes[k - 1].t_ns, t) <= d))) {
      continue;
    }
    serves[j] = k;
  }
  return serves;
}

// The sample each keyframe takes in the factors of a sensor on a clock offset_s from the IMU's
// (Eq. K17): NearestSamples within half the sensor's maximum gap between samples.
template <typename Sample>
std::vector<std::optional<size_t>> PairedSamples(const std::vector<Sample>& samples,
                                                 const std::vector<Keyframe>& keyframes,
                                                 double offset_s, int64_t max_gap_ns) {
  return NearestSamples(samples, keyframes, SecondsToNs(offset_s), max_gap_ns / 2);
}

// A maximum gap in seconds as nanoseconds; throws autocal::Error naming `name` unless it is
// a positive number.
int64_t GapNs(double gap_s, const std::string& name);

// A maximum bracketing gap option as nanoseconds: gap_s when it is set, else (0, the options'
// default) Eq. T1 from the samples' own stamps (sensors::MaxBracketingGapS), so that a caller
// who keeps the default gets the limit its sensor's rate needs, not one written for another
// rate. Fewer than two samples have no interval: only a sample on a keyframe's stamp brackets
// it. Throws autocal::Error as GapNs for a negative, non-finite or too large gap_s, or as
// sensors::MeasureTiming for stamps that do not increase.
template <typename Sample>
int64_t GapNsOrFromStamps(double gap_s, const std::vector<Sample>& samples,
                          const std::string& name) {
  if (gap_s == 0.0) {
    if (samples.size() < 2) return 1;
    const sensors::SampleTiming timing = sensors::MeasureTiming(sensors::StampsOf(samples), name);
    return GapNs(sensors::MaxBracketingGapS(timing), name);
  }
  if (!(gap_s > 0.0)) {
    throw Error(name +
                " must be 0 (from the stamps, Eq. T1) or a positive number of seconds, got " +
                std::to_string(gap_s));
  }
  return GapNs(gap_s, name);
}

// InterpolateGnss on fixes known to be in time order.
bool InterpolateSortedGnss(const sensors::GnssFixes& fixes, const sensors::EnuConverter& converter,
                           int64_t t_ns, int64_t max_gap_ns, factors::GnssMeasurement* measurement);

// The nearest flagged entry at or before each entry (step +1), or at or after it (step -1):
// two such passes find every entry's flagged neighbours in linear time.
inline std::vector<std::optional<size_t>> NearestFlagged(const std::vector<bool>& flag, int step) {
  const size_t n = flag.size();
  std::vector<std::optional<size_t>> nearest(n);
  std::optional<size_t> last;
  for (size_t m = 0; m < n; ++m) {
    const size_t k = step > 0 ? m : n - 1 - m;
    if (flag[k]) last = k;
    nearest[k] = last;
  }
  return nearest;
}

// An angle wrapped into [-pi, pi].
inline double WrapAngle(double a) { return std::atan2(std::sin(a), std::cos(a)); }

// The heading (from x_W towards y_W) of the vehicle's forward axis R_W_I R_I_V x.
inline double ForwardHeading(const Keyframe& kf, const Eigen::Quaterniond& q_I_V) {
  const Eigen::Vector3d forward_W = kf.q_W_I * (q_I_V * Eigen::Vector3d::UnitX());
  return std::atan2(forward_W.y(), forward_W.x());
}

// The gyro integrated about the vehicle's up axis (R_I_V z, in I) from the first keyframe to
// each keyframe (trapezoids between samples, linear within one): the keyframes' relative yaw,
// so that a turning platform's keyframes start with their own headings (Eq. K11 and dead
// reckoning need them). The gyro bias is unknown here; its drift is left to the caller's solve.
inline std::vector<double> GyroYawAtKeyframes(const sensors::ImuSamples& imu,
                                              const std::vector<Keyframe>& kfs,
                                              const Eigen::Vector3d& up_I) {
  std::vector<double> yaw_rad(kfs.size(), 0.0);
  size_t i = 0;
  double integral_rad = 0.0;  // up to imu[i]
  const auto rate = [&](size_t j) { return imu[j].gyro_rad_s.dot(up_I); };
  const auto at = [&](int64_t t_ns) {
    while (i + 1 < imu.size() && imu[i + 1].t_ns <= t_ns) {
      integral_rad += 0.5 * (rate(i) + rate(i + 1)) * NsToSeconds(imu[i + 1].t_ns - imu[i].t_ns);
      ++i;
    }
    if (i + 1 >= imu.size()) return integral_rad;
    const double dt_s = NsToSeconds(t_ns - imu[i].t_ns);
    const double s = dt_s / NsToSeconds(imu[i + 1].t_ns - imu[i].t_ns);
    return integral_rad + dt_s * (rate(i) + 0.5 * s * (rate(i + 1) - rate(i)));
  };
  const double first_rad = at(kfs.front().t_ns);
  for (size_t k = 0; k < kfs.size(); ++k) yaw_rad[k] = at(kfs[k].t_ns) - first_rad;
  return yaw_rad;
}

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
