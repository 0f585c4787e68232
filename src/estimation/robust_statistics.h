#pragma once

// Order statistics shared by the estimation module's robust fits.

#include <algorithm>
#include <cstddef>
#include <vector>

namespace autocal {
namespace estimation {
namespace internal {

// The middle element of `values` (the upper one for an even count); `values` is not empty.
inline double Median(std::vector<double> values) {
  const auto middle = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), middle, values.end());
  return *middle;
}

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
