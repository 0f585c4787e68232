#include "autocal/estimation/clock_offsets.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <string>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/format.h"
#include "autocal/common/time.h"
#include "autocal/sensors/gnss_enu.h"
#include "common/order_statistics.h"
#include "estimation/correlation_peak.h"

namespace autocal {
namespace estimation {

namespace {

void CheckSeries(const ScalarSeries& series, const char* name) {
  for (size_t i = 0; i < series.size(); ++i) {
    if (!std::isfinite(series[i].value)) {
      throw Error(std::string("EstimateSeriesOffset: the ") + name + " series has a non-finite " +
                  "value at sample " + std::to_string(i));
    }
    if (i > 0 && series[i].t_ns <= series[i - 1].t_ns) {
      throw Error(std::string("EstimateSeriesOffset: the ") + name +
                  " series is not in strictly increasing time at sample " + std::to_string(i));
    }
  }
}

double MedianIntervalS(const ScalarSeries& series) {
  std::vector<int64_t> dt;
  for (size_t i = 1; i < series.size(); ++i) dt.push_back(series[i].t_ns - series[i - 1].t_ns);
  std::nth_element(dt.begin(), dt.begin() + dt.size() / 2, dt.end());
  return NsToSeconds(dt[dt.size() / 2]);
}

double StandardDeviation(const std::vector<double>& v) {
  if (v.size() < 2) return 0.0;
  double mean = 0.0;
  for (double x : v) mean += x;
  mean /= static_cast<double>(v.size());
  double sum_sq = 0.0;
  for (double x : v) sum_sq += (x - mean) * (x - mean);
  return std::sqrt(sum_sq / static_cast<double>(v.size() - 1));
}

// Linear interpolation of `series` at increasing times (a cursor that only moves forward).
// Times must lie within [front, back].
class ForwardInterpolator {
 public:
  explicit ForwardInterpolator(const ScalarSeries& series) : series_(series) {}
  double At(int64_t t_ns) {
    while (i_ + 2 < series_.size() && series_[i_ + 1].t_ns <= t_ns) ++i_;
    const TimedValue& a = series_[i_];
    const TimedValue& b = series_[i_ + 1];
    const double w = SecondsBetween(a.t_ns, t_ns) / SecondsBetween(a.t_ns, b.t_ns);
    return a.value + w * (b.value - a.value);
  }

 private:
  const ScalarSeries& series_;
  size_t i_ = 0;
};

// The sparser series' samples against the denser one interpolated at the shifted stamps.
struct Comparison {
  // The denser series averaged over the sparser one's interval (and at least four of its
  // own): interpolating raw noisy samples halfway between two of them averages their noise,
  // which would raise the correlation of offsets that fall between dense samples.
  ScalarSeries dense;
  double sign = 1.0;  // dense time = sparse time + sign * offset
  // The offsets +-range_ns for which every compared sample's shifted stamp was checked to lie
  // inside the denser series.
  int64_t range_ns = 0;
  std::vector<int64_t> t_ns;
  std::vector<double> sparse_values;
  bool sparse_is_sensor = true;
  // Standard deviations of the sparse values and of the raw dense samples over their span.
  double sparse_std = 0.0;
  double dense_std = 0.0;

  // Throws autocal::Error for an offset outside the checked range (1 ns of rounding aside),
  // where the interpolation would extrapolate the denser series past its ends.
  void Interpolate(double offset_s, std::vector<double>* dense_values) const {
    const int64_t shift_ns = SecondsToNs(sign * offset_s);
    if (!(std::abs(shift_ns) <= range_ns + 1)) {
      throw Error("EstimateSeriesOffset: the candidate offset " + FormatShort(offset_s) +
                  " s lies outside the range +-" + FormatShort(NsToSeconds(range_ns)) +
                  " s over which the series were checked to overlap");
    }
    ForwardInterpolator interpolator(dense);
    dense_values->resize(t_ns.size());
    for (size_t i = 0; i < t_ns.size(); ++i)
      (*dense_values)[i] = interpolator.At(t_ns[i] + shift_ns);
  }
};

Comparison MakeComparison(const ScalarSeries& reference, const ScalarSeries& sensor,
                          double range_s) {
  Comparison c;
  c.sparse_is_sensor = MedianIntervalS(sensor) >= MedianIntervalS(reference);
  const ScalarSeries& sparse = c.sparse_is_sensor ? sensor : reference;
  const ScalarSeries& dense = c.sparse_is_sensor ? reference : sensor;
  c.dense = MovingAverage(dense, std::max(MedianIntervalS(sparse), 4.0 * MedianIntervalS(dense)));
  c.sign = c.sparse_is_sensor ? 1.0 : -1.0;
  const int64_t range_ns = SecondsToNs(range_s);
  c.range_ns = range_ns;
  for (const TimedValue& s : sparse) {
    if (s.t_ns - range_ns < dense.front().t_ns || s.t_ns + range_ns > dense.back().t_ns) {
      continue;
    }
    c.t_ns.push_back(s.t_ns);
    c.sparse_values.push_back(s.value);
  }
  c.sparse_std = StandardDeviation(c.sparse_values);
  std::vector<double> dense_values;
  for (const TimedValue& d : dense) {
    if (!c.t_ns.empty() && d.t_ns >= c.t_ns.front() && d.t_ns <= c.t_ns.back()) {
      dense_values.push_back(d.value);
    }
  }
  c.dense_std = StandardDeviation(dense_values);
  return c;
}

// A strong negative correlation means one signal has the opposite sign convention.
std::string AntiCorrelation(const internal::CorrelationScan& scan, double threshold) {
  const auto low = std::min_element(scan.correlation.begin(), scan.correlation.end());
  if (*low > -threshold || -*low <= scan.correlation[scan.peak]) return "";
  const double at_s = scan.offsets_s[static_cast<size_t>(low - scan.correlation.begin())];
  return "the signals are anti-correlated (r = " + FormatFixed(*low, 3) + " at " +
         FormatFixed(at_s, 3) + " s): does one of them use the opposite sign?";
}

}  // namespace

SeriesOffsetEstimate EstimateSeriesOffset(const ScalarSeries& reference, const ScalarSeries& sensor,
                                          const SeriesOffsetOptions& options) {
  CheckSeries(reference, "reference");
  CheckSeries(sensor, "sensor");
  SeriesOffsetEstimate out;
  if (reference.size() < 2 || sensor.size() < 2) {
    out.reason = "a series has fewer than 2 samples";
    return out;
  }
  const double range_s = options.search_range_s;
  const Comparison comparison = MakeComparison(reference, sensor, range_s);
  out.pairs = comparison.t_ns.size();
  if (out.pairs < std::max<size_t>(options.min_pairs, 3)) {
    out.reason = "only " + std::to_string(out.pairs) + " samples overlap the other series by " +
                 FormatFixed(range_s, 2) + " s on both sides (need " +
                 std::to_string(options.min_pairs) + ")";
    return out;
  }
  const double slower_s = std::max(MedianIntervalS(reference), MedianIntervalS(sensor));
  out.slower_interval_s = slower_s;
  const double faster_s = std::min(MedianIntervalS(reference), MedianIntervalS(sensor));
  const double coarse_s =
      options.step_s > 0.0 ? options.step_s : std::clamp(0.5 * slower_s, 0.002, 0.05);
  const double fine_s = std::clamp(0.25 * faster_s, 0.0005, coarse_s);
  std::vector<double> dense_values;
  const auto correlation_at = [&](double offset_s) {
    comparison.Interpolate(offset_s, &dense_values);
    return internal::Pearson(comparison.sparse_values, dense_values);
  };
  const internal::CorrelationScan coarse =
      internal::ScanCorrelation(0.0, range_s, coarse_s, correlation_at);
  out.candidate_offsets_s = coarse.offsets_s;
  out.correlation = coarse.correlation;
  // The fine scan covers two coarse steps either side of the coarse peak, cut to the range
  // whose coverage MakeComparison checked: a peak at or next to the range's edge would take it
  // up to two steps beyond, where the interpolation extrapolates the denser series.
  const double peak_s = coarse.offsets_s[coarse.peak];
  double fine_centre_s = peak_s;
  double fine_half_s = 2.0 * coarse_s;
  if (peak_s - fine_half_s < -range_s || peak_s + fine_half_s > range_s) {
    const double low_s = std::max(peak_s - fine_half_s, -range_s);
    const double high_s = std::min(peak_s + fine_half_s, range_s);
    fine_centre_s = 0.5 * (low_s + high_s);
    fine_half_s = 0.5 * (high_s - low_s);  // at least coarse_s, since coarse_s <= range_s
  }
  const internal::CorrelationScan fine =
      internal::ScanCorrelation(fine_centre_s, fine_half_s, fine_s, correlation_at);
  out.offset_s = internal::FitParabolaPeak(fine).value_or(fine.refined_offset_s);
  out.peak_correlation = correlation_at(out.offset_s);
  out.sensor_std = comparison.sparse_is_sensor ? comparison.sparse_std : comparison.dense_std;
  out.reference_std = comparison.sparse_is_sensor ? comparison.dense_std : comparison.sparse_std;
  if (out.reference_std < options.min_reference_std || out.sensor_std < options.min_sensor_std) {
    out.reason = "too little variation to align: standard deviation " +
                 FormatFixed(out.reference_std, 4) + " (reference) and " +
                 FormatFixed(out.sensor_std, 4) + " (sensor), need " +
                 FormatFixed(options.min_reference_std, 4) + " and " +
                 FormatFixed(options.min_sensor_std, 4);
    return out;
  }
  const std::string anti = AntiCorrelation(coarse, options.min_peak_correlation);
  if (!anti.empty()) {
    out.reason = anti;
    return out;
  }
  if (coarse.peak_at_edge) {
    out.offset_s = coarse.offsets_s[coarse.peak];
    out.reason = "the correlation peaks at the edge of the search range (" +
                 FormatFixed(out.offset_s, 3) + " s): the offset may lie outside +-" +
                 FormatFixed(range_s, 2) + " s";
    return out;
  }
  if (out.peak_correlation < options.min_peak_correlation) {
    out.reason = "the peak correlation " + FormatFixed(out.peak_correlation, 3) + " at " +
                 FormatFixed(out.offset_s, 3) + " s is below " +
                 FormatFixed(options.min_peak_correlation, 2) +
                 ": the signals do not agree well enough to align them";
    return out;
  }
  out.reliable = true;
  return out;
}

ScalarSeries GyroAbout(const sensors::ImuSamples& imu, const Eigen::Vector3d& axis_I) {
  ScalarSeries out;
  out.reserve(imu.size());
  for (const sensors::ImuSample& s : imu) out.push_back({s.t_ns, axis_I.dot(s.gyro_rad_s)});
  return out;
}

ScalarSeries AccelAlong(const sensors::ImuSamples& imu, const Eigen::Vector3d& axis_I) {
  ScalarSeries out;
  out.reserve(imu.size());
  for (const sensors::ImuSample& s : imu) out.push_back({s.t_ns, axis_I.dot(s.accel_m_s2)});
  return out;
}

ScalarSeries CentralDerivative(const ScalarSeries& series) {
  ScalarSeries out;
  for (size_t i = 1; i + 1 < series.size(); ++i) {
    const double dt_s = SecondsBetween(series[i - 1].t_ns, series[i + 1].t_ns);
    out.push_back({series[i].t_ns, (series[i + 1].value - series[i - 1].value) / dt_s});
  }
  return out;
}

ScalarSeries MovingAverage(const ScalarSeries& series, double width_s) {
  const int64_t half_ns = SecondsToNs(0.5 * width_s);
  ScalarSeries out;
  out.reserve(series.size());
  size_t lo = 0, hi = 0;
  double sum = 0.0;
  for (const TimedValue& s : series) {
    while (hi < series.size() && series[hi].t_ns <= s.t_ns + half_ns) sum += series[hi++].value;
    while (series[lo].t_ns < s.t_ns - half_ns) sum -= series[lo++].value;
    out.push_back({s.t_ns, sum / static_cast<double>(hi - lo)});
  }
  return out;
}

double InterpolateSeries(const ScalarSeries& series, int64_t t_ns) {
  const auto it = std::lower_bound(series.begin(), series.end(), t_ns,
                                   [](const TimedValue& s, int64_t t) { return s.t_ns < t; });
  if (it == series.begin()) return series.front().value;
  if (it == series.end()) return series.back().value;
  const TimedValue& a = *(it - 1);
  const TimedValue& b = *it;
  return a.value +
         SecondsBetween(a.t_ns, t_ns) / SecondsBetween(a.t_ns, b.t_ns) * (b.value - a.value);
}

namespace {

SeriesOffsetEstimate AccelerationOffset(const sensors::ImuSamples& imu,
                                        const ScalarSeries& wheel_speed_m_s,
                                        const Eigen::Vector3d& forward_I,
                                        const WheelImuOffsetOptions& options) {
  SeriesOffsetOptions series = options.series;
  series.min_reference_std = std::max(series.min_reference_std, options.min_accel_std_m_s2);
  series.min_sensor_std = std::max(series.min_sensor_std, options.min_accel_std_m_s2);
  const ScalarSeries imu_accel =
      MovingAverage(AccelAlong(imu, forward_I), options.accel_smoothing_s);
  const ScalarSeries wheel_accel =
      MovingAverage(CentralDerivative(wheel_speed_m_s), options.accel_smoothing_s);
  return EstimateSeriesOffset(imu_accel, wheel_accel, series);
}

}  // namespace

WheelImuOffset EstimateWheelImuOffset(const sensors::ImuSamples& imu,
                                      const ScalarSeries& wheel_speed_m_s,
                                      const ScalarSeries& wheel_yaw_rate_rad_s,
                                      const Eigen::Quaterniond& q_I_V,
                                      const WheelImuOffsetOptions& options) {
  WheelImuOffset out;
  std::vector<double> yaw_rates;
  for (const TimedValue& s : wheel_yaw_rate_rad_s) yaw_rates.push_back(s.value);
  const double yaw_std = StandardDeviation(yaw_rates);
  const bool turns = yaw_std >= options.min_yaw_rate_std_rad_s;
  if (turns) {
    SeriesOffsetOptions series = options.series;
    series.min_sensor_std = std::max(series.min_sensor_std, options.min_yaw_rate_std_rad_s);
    out.yaw_rate = EstimateSeriesOffset(GyroAbout(imu, q_I_V * Eigen::Vector3d::UnitZ()),
                                        wheel_yaw_rate_rad_s, series);
    out.estimate = out.yaw_rate;
    out.signal = "yaw rate";
    if (out.yaw_rate.reliable) return out;
  }
  out.acceleration =
      AccelerationOffset(imu, wheel_speed_m_s, q_I_V * Eigen::Vector3d::UnitX(), options);
  if (out.acceleration.reliable || !turns) {
    out.estimate = out.acceleration;
    out.signal = "forward acceleration";
    if (!turns) {
      out.estimate.reason = "the wheel yaw rate hardly varies (standard deviation " +
                            FormatFixed(yaw_std, 4) + " rad/s), so the forward acceleration " +
                            "was compared" +
                            (out.estimate.reliable ? "" : ": " + out.acceleration.reason);
    }
    return out;
  }
  out.estimate.reason +=
      "; the forward acceleration does not help either: " + out.acceleration.reason;
  return out;
}

namespace {

// A multipath fix metres off spoils the two speeds that pair it, a baseline apart, with spikes
// of metres per second; the median of 2 k + 1 neighbouring speeds drops such isolated spikes
// and, being symmetric, shifts no speed change in time.
constexpr size_t kSpeedMedianHalfWindow = 2;

ScalarSeries RunningMedian(const ScalarSeries& series, size_t half_window) {
  ScalarSeries out = series;
  std::vector<double> window;
  for (size_t i = half_window; i + half_window < series.size(); ++i) {
    window.clear();
    for (size_t k = i - half_window; k <= i + half_window; ++k) window.push_back(series[k].value);
    out[i].value = autocal::internal::Median(window);
  }
  return out;
}

}  // namespace

ScalarSeries GnssHorizontalSpeed(const sensors::GnssFixes& fixes, double baseline_s) {
  ScalarSeries out;
  if (fixes.size() < 2) return out;
  const sensors::EnuConverter enu = sensors::EnuConverter::AtFirstFix(fixes);
  std::vector<Eigen::Vector3d> p;
  for (const sensors::GnssFix& f : fixes) p.push_back(enu.ToEnu(f));
  const int64_t baseline_ns = SecondsToNs(baseline_s);
  size_t j = 1;
  for (size_t i = 0; i < fixes.size(); ++i) {
    j = std::max(j, i + 1);
    while (j < fixes.size() && fixes[j].t_ns - fixes[i].t_ns < baseline_ns) ++j;
    if (j >= fixes.size()) break;
    const double dt_s = SecondsBetween(fixes[i].t_ns, fixes[j].t_ns);
    const double distance_m = (p[j] - p[i]).head<2>().norm();
    out.push_back({fixes[i].t_ns + (fixes[j].t_ns - fixes[i].t_ns) / 2, distance_m / dt_s});
  }
  return RunningMedian(out, kSpeedMedianHalfWindow);
}

SeriesOffsetEstimate EstimateGnssImuOffset(const sensors::GnssFixes& fixes,
                                           const ScalarSeries& wheel_speed_on_imu_clock_m_s,
                                           const GnssImuOffsetOptions& options) {
  ScalarSeries wheel_speed = wheel_speed_on_imu_clock_m_s;
  for (TimedValue& s : wheel_speed) s.value = std::abs(s.value);
  SeriesOffsetOptions series = options.series;
  series.min_reference_std = std::max(series.min_reference_std, options.min_speed_std_m_s);
  series.min_sensor_std = std::max(series.min_sensor_std, options.min_speed_std_m_s);
  return EstimateSeriesOffset(MovingAverage(wheel_speed, options.speed_baseline_s),
                              GnssHorizontalSpeed(fixes, options.speed_baseline_s), series);
}

YawRateAgreement CompareYawRates(const sensors::ImuSamples& imu,
                                 const ScalarSeries& wheel_speed_m_s,
                                 const ScalarSeries& wheel_yaw_rate_rad_s, double offset_s,
                                 const Eigen::Vector3d& up_I) {
  YawRateAgreement out;
  if (imu.size() < 2 || wheel_yaw_rate_rad_s.size() < 10 ||
      wheel_speed_m_s.size() != wheel_yaw_rate_rad_s.size()) {
    return out;
  }
  const int64_t shift_ns = SecondsToNs(offset_s);
  const ScalarSeries& yaw = wheel_yaw_rate_rad_s;
  const double interval_s =
      SecondsBetween(yaw.front().t_ns, yaw.back().t_ns) / static_cast<double>(yaw.size() - 1);
  const ScalarSeries gyro = MovingAverage(GyroAbout(imu, up_I), interval_s);
  std::vector<Eigen::Vector3d> rows;  // (yaw rate, speed, 1)
  std::vector<double> measured;       // the gyro
  for (size_t i = 0; i < yaw.size(); ++i) {
    const int64_t t_ns = yaw[i].t_ns + shift_ns;
    if (t_ns < imu.front().t_ns || t_ns > imu.back().t_ns) continue;
    rows.emplace_back(yaw[i].value, wheel_speed_m_s[i].value, 1.0);
    measured.push_back(InterpolateSeries(gyro, t_ns));
  }
  if (rows.size() < 10) return out;
  Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
  Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < rows.size(); ++i) {
    normal += rows[i] * rows[i].transpose();
    rhs += rows[i] * measured[i];
  }
  const Eigen::LDLT<Eigen::Matrix3d> ldlt(normal);
  if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().minCoeff() > 1e-9 * normal.trace())) {
    return out;
  }
  const Eigen::Vector3d fit = ldlt.solve(rhs);
  std::vector<double> residuals;
  residuals.reserve(rows.size());
  for (size_t i = 0; i < rows.size(); ++i) residuals.push_back(measured[i] - rows[i].dot(fit));
  const double centre = autocal::internal::Median(residuals);
  for (double& r : residuals) r = std::abs(r - centre);
  out.samples = rows.size();
  out.scale = fit(0);
  out.per_speed_rad_m = fit(1);
  out.bias_rad_s = fit(2);
  out.residual_sigma_rad_s = 1.4826 * autocal::internal::Median(residuals);
  return out;
}

}  // namespace estimation
}  // namespace autocal
