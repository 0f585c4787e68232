#pragma once

// How a sensor's stamps are spaced, and the limits the offline calibration derives from it
// (docs/keyframe_factors.md, "Limits from the log's timing").
//
// Real logs do not tick like a simulator: a phone-grade IMU at 30 Hz, wheel odometry at 10 Hz
// with 10 % jitter, CAN wheel speeds at 83 Hz that arrive in bursts (several samples within a
// millisecond, then a gap), GNSS from 1 to 20 Hz with outages. Limits written as constants for
// one set of rates (200 Hz IMU, 100 Hz wheels, 10 Hz GNSS) leave such a log without factors.
// So every limit that depends on a rate follows from the log's own stamps:
//
//   max bracketing gap  = max(2.5 * mean interval, 1.2 * p99 interval)           (Eq. T1)
//   keyframe period     = clamp(max(1 / f_gnss, 3 / f_imu, 1 / f_wheel), 0.05, 0.5) s  (T2)
//   GNSS track window   = max(1.0, 2.5 / f_gnss) s on each side of a keyframe    (Eq. T3)
//
// T1: 2.5 mean intervals bridge one lost sample of a regular stream but not a dropout; the
// 1.2 * p99 term keeps a jittered or bursty stream (whose long intervals are the rule, not
// the exception) bracketed. T2: a keyframe per fix (each gets its own GNSS factor), at least
// three IMU samples and one wheel sample between keyframes; 50 ms to 0.5 s keeps the problem's
// size and the IMU preintegration's linearization in bounds. T3: the quadratic track fit
// (Eq. K7) needs at least five fixes around a keyframe. At 200 / 100 / 10 Hz these give the
// former constants: gaps 0.0125 / 0.025 / 0.25 s, period 0.1 s, window 1 s.
//
// f = 1 / mean interval. The mean interval leaves out outages (intervals longer than five
// typical ones), which say nothing about the rate: a 10 Hz receiver with two 4 s outages in
// 34 s is still a 10 Hz receiver.

#include <cstdint>
#include <string>
#include <vector>

namespace autocal {
namespace sensors {

struct SampleTiming {
  int64_t count = 0;               // stamps
  double span_s = 0.0;             // last - first
  double mean_interval_s = 0.0;    // span over the intervals without outages, per interval
  double median_interval_s = 0.0;  // ~0 for a bursty stream
  double p99_interval_s = 0.0;     // 99th percentile of the intervals without outages
  double max_gap_s = 0.0;          // the longest interval (outages included)
  int64_t outages = 0;             // intervals over five typical ones (left out of the mean)
  // The median interval is below half the mean: samples arrive in bursts, so the median
  // says nothing about the rate (the mean does).
  bool bursty = false;

  double rate_hz() const { return 1.0 / mean_interval_s; }
};

// The stamps of `samples` (any samples with a t_ns), for MeasureTiming.
template <typename Samples>
std::vector<int64_t> StampsOf(const Samples& samples) {
  std::vector<int64_t> stamps;
  stamps.reserve(samples.size());
  for (const auto& sample : samples) stamps.push_back(sample.t_ns);
  return stamps;
}

// The timing of `stamps_ns` (strictly increasing, as every reader of the dataset requires).
// `what` names them in errors ("wheel.csv"). Throws autocal::Error for fewer than two stamps
// or a stamp that does not follow its predecessor, naming which.
SampleTiming MeasureTiming(const std::vector<int64_t>& stamps_ns, const std::string& what);

// Eq. T1: the longest interval between the two samples that bracket a keyframe for the
// interpolation there (Eq. K1) to be trusted.
double MaxBracketingGapS(const SampleTiming& timing);

// Eq. T2. `wheel` may be null (no wheel encoders in the problem).
double KeyframePeriodS(const SampleTiming& gnss, const SampleTiming& imu,
                       const SampleTiming* wheel);
// Eq. T2 without a receiver (the IMU and the wheels alone).
double KeyframePeriodS(const SampleTiming& imu, const SampleTiming* wheel);

// Eq. T3: the half-width of the window of fixes fitted around a keyframe.
double GnssTrackHalfWidthS(const SampleTiming& gnss);

}  // namespace sensors
}  // namespace autocal
