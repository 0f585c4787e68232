#pragma once

#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string>

namespace autocal {

// Data carries int64 nanoseconds; math uses double seconds relative to a reference time
// (never raw epoch seconds inside a residual).
constexpr int64_t kNanosecondsPerSecond = 1'000'000'000;

constexpr double NsToSeconds(int64_t t_ns) { return static_cast<double>(t_ns) * 1e-9; }

// Seconds between two stamps, computed in integers first so that epoch-sized stamps keep
// full precision.
constexpr double SecondsBetween(int64_t from_ns, int64_t to_ns) {
  return NsToSeconds(to_ns - from_ns);
}

inline int64_t SecondsToNs(double t_s) { return static_cast<int64_t>(std::llround(t_s * 1e9)); }

// Wall time (steady clock) since `start`, for the stages' timings.
inline double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// A stamp as seconds with all nine decimals ("1700000000.123456789", "-0.000000001"), so that
// it reads back to the same nanosecond (a double holds only ~16 digits of an epoch stamp).
inline std::string FormatSeconds(int64_t t_ns) {
  const bool negative = t_ns < 0;
  const uint64_t magnitude =
      negative ? 0 - static_cast<uint64_t>(t_ns) : static_cast<uint64_t>(t_ns);
  char buffer[48];
  std::snprintf(buffer, sizeof(buffer), "%s%llu.%09llu", negative ? "-" : "",
                static_cast<unsigned long long>(magnitude / 1000000000ULL),
                static_cast<unsigned long long>(magnitude % 1000000000ULL));
  return buffer;
}

}  // namespace autocal
