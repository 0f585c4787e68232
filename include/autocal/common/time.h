#pragma once

#include <cmath>
#include <cstdint>

namespace autocal {

// Data carries int64 nanoseconds; math uses double seconds relative to a reference time
// (never raw epoch seconds inside a residual).
constexpr int64_t kNanosecondsPerSecond = 1'000'000'000;

constexpr double NsToSeconds(int64_t t_ns) {
  return static_cast<double>(t_ns) * 1e-9;
}

// Seconds between two stamps, computed in integers first so that epoch-sized stamps keep
// full precision.
constexpr double SecondsBetween(int64_t from_ns, int64_t to_ns) {
  return NsToSeconds(to_ns - from_ns);
}

inline int64_t SecondsToNs(double t_s) { return static_cast<int64_t>(std::llround(t_s * 1e9)); }

}  // namespace autocal
