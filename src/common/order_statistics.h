#pragma once

// Order statistics shared by the robust fits (sensor statistics, estimation, pipeline).

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <utility>
#include <vector>

namespace autocal {
namespace internal {

// The middle element of `values` (the upper one for an even count); `values` is not empty.
inline double Median(std::vector<double> values) {
  const auto middle = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), middle, values.end());
  return *middle;
}

// The standard deviation of Gaussian `values` from their median absolute deviation
// (1.4826 MAD): blind to a minority of outliers. `values` is not empty.
inline double MadSigma(const std::vector<double>& values) {
  const double centre = Median(values);
  std::vector<double> deviations;
  deviations.reserve(values.size());
  for (const double v : values) deviations.push_back(std::abs(v - centre));
  return 1.4826 * Median(std::move(deviations));
}

}  // namespace internal
}  // namespace autocal
