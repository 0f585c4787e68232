#pragma once

// How many independent samples a correlated series is worth (docs/keyframe_factors.md,
// Eqs. K15 and K16).

#include <cmath>
#include <cstddef>
#include <vector>

namespace autocal {
namespace internal {

// sqrt(1 + 2 sum_{L >= 1} rho(L)) of a centred series, the autocorrelation rho summed up to
// the first lag where it is not positive (at most a quarter of the series): the variance of
// the series' mean is this squared times that of independent samples. An AR(1) series with
// coefficient a gives sqrt((1 + a) / (1 - a)); a white one about 1.
inline double CorrelationScale(const std::vector<double>& centred) {
  const size_t n = centred.size();
  double c0 = 0.0;
  for (double v : centred) c0 += v * v;
  if (!(c0 > 0.0)) return 1.0;
  double sum = 0.0;
  for (size_t lag = 1; lag < n / 4; ++lag) {
    double c = 0.0;
    for (size_t i = 0; i + lag < n; ++i) c += centred[i] * centred[i + lag];
    const double rho = c / c0;
    if (rho <= 0.0) break;
    sum += rho;
  }
  return std::sqrt(1.0 + 2.0 * sum);
}

}  // namespace internal
}  // namespace autocal
