#include "autocal/sensors/sample_timing.h"

#include <algorithm>
#include <cmath>
#include <cstddef>

#include "autocal/common/error.h"
#include "autocal/common/time.h"

namespace autocal {
namespace sensors {
namespace {

// An interval over this many typical ones is an outage: left out of the rate (docs T1).
constexpr double kOutageFactor = 5.0;

// The value at `fraction` of the sorted values by nearest rank (0.5: the median, the upper
// one of an even count).
int64_t NearestRank(const std::vector<int64_t>& sorted, double fraction) {
  const double rank = std::ceil(fraction * static_cast<double>(sorted.size()));
  const size_t index = static_cast<size_t>(std::max(1.0, rank)) - 1;
  return sorted[std::min(index, sorted.size() - 1)];
}

// A typical interval that neither bursts nor outages distort: the one the log's median instant
// falls in (the intervals sorted, each weighted by its length). Bursts put almost all of the
// time in the gaps between them, and outages shorter than half the log's span leave the median
// instant outside them. (The mean of the intervals up to the 90th percentile, before, fell
// inside the bursts once a burst held ten samples, and called every gap between bursts an
// outage once it held six.)
double TypicalIntervalNs(const std::vector<int64_t>& sorted) {
  double total = 0.0;
  for (int64_t interval : sorted) total += static_cast<double>(interval);
  double covered = 0.0;
  for (int64_t interval : sorted) {
    covered += static_cast<double>(interval);
    if (covered >= 0.5 * total) return static_cast<double>(interval);
  }
  return static_cast<double>(sorted.back());
}

}  // namespace

SampleTiming MeasureTiming(const std::vector<int64_t>& stamps_ns, const std::string& what) {
  if (stamps_ns.size() < 2) {
    throw Error(what + ": " + std::to_string(stamps_ns.size()) +
                " stamp(s); the timing needs at least two");
  }
  std::vector<int64_t> intervals_ns(stamps_ns.size() - 1);
  for (size_t i = 1; i < stamps_ns.size(); ++i) {
    if (stamps_ns[i] <= stamps_ns[i - 1]) {
      throw Error(what + ": stamps must increase: stamp " + std::to_string(i) + " at " +
                  std::to_string(stamps_ns[i]) + " ns follows " + std::to_string(stamps_ns[i - 1]) +
                  " ns");
    }
    intervals_ns[i - 1] = stamps_ns[i] - stamps_ns[i - 1];
  }
  std::sort(intervals_ns.begin(), intervals_ns.end());
  const double outage_ns = kOutageFactor * TypicalIntervalNs(intervals_ns);
  std::vector<int64_t> regular;  // sorted, without outages
  for (int64_t interval : intervals_ns) {
    if (static_cast<double>(interval) <= outage_ns) regular.push_back(interval);
  }
  SampleTiming t;
  t.count = static_cast<int64_t>(stamps_ns.size());
  t.span_s = NsToSeconds(stamps_ns.back() - stamps_ns.front());
  t.outages = static_cast<int64_t>(intervals_ns.size() - regular.size());
  int64_t regular_span_ns = 0;
  for (int64_t interval : regular) regular_span_ns += interval;
  t.mean_interval_s = NsToSeconds(regular_span_ns) / static_cast<double>(regular.size());
  t.median_interval_s = NsToSeconds(NearestRank(intervals_ns, 0.5));
  t.p99_interval_s = NsToSeconds(NearestRank(regular, 0.99));
  t.max_gap_s = NsToSeconds(intervals_ns.back());
  t.bursty = t.median_interval_s < 0.5 * t.mean_interval_s;
  return t;
}

double MaxBracketingGapS(const SampleTiming& timing) {
  return std::max(2.5 * timing.mean_interval_s, 1.2 * timing.p99_interval_s);
}

double KeyframePeriodS(const SampleTiming& gnss, const SampleTiming& imu,
                       const SampleTiming* wheel) {
  return std::clamp(std::max(gnss.mean_interval_s, KeyframePeriodS(imu, wheel)), 0.05, 0.5);
}

double KeyframePeriodS(const SampleTiming& imu, const SampleTiming* wheel) {
  double period_s = 3.0 * imu.mean_interval_s;
  if (wheel != nullptr) period_s = std::max(period_s, wheel->mean_interval_s);
  return std::clamp(period_s, 0.05, 0.5);
}

double GnssTrackHalfWidthS(const SampleTiming& gnss) {
  return std::max(1.0, 2.5 * gnss.mean_interval_s);
}

}  // namespace sensors
}  // namespace autocal
