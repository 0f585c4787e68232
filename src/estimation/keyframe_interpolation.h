#pragma once

// Measurements interpolated to keyframe instants (docs/keyframe_factors.md, Eq. K1), shared by
// the keyframe factors and the GNSS alignment of keyframes.

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/factors/gnss_factor.h"
#include "autocal/sensors/gnss_enu.h"
#include "autocal/sensors/measurements.h"

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

// A maximum gap in seconds as nanoseconds; throws autocal::Error naming `name` unless it is
// a positive number.
int64_t GapNs(double gap_s, const std::string& name);

// InterpolateGnss on fixes known to be in time order.
bool InterpolateSortedGnss(const sensors::GnssFixes& fixes, const sensors::EnuConverter& converter,
                           int64_t t_ns, int64_t max_gap_ns, factors::GnssMeasurement* measurement);

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
