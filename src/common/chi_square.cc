#include "autocal/common/chi_square.h"

#include <cmath>

namespace autocal {
namespace {

// Q(a, x) = Gamma(a, x) / Gamma(a): below x = a + 1 from the series of P = 1 - Q, beyond it
// from the continued fraction of Q (modified Lentz); both converge in a few dozen terms there.
double RegularizedUpperGamma(double a, double x) {
  const double log_prefactor = -x + a * std::log(x) - std::lgamma(a);
  if (x < a + 1.0) {
    double term = 1.0 / a, sum = term;
    for (int n = 1; n < 1000 && std::abs(term) > 1e-16 * std::abs(sum); ++n) {
      term *= x / (a + n);
      sum += term;
    }
    return 1.0 - sum * std::exp(log_prefactor);
  }
  constexpr double kTiny = 1e-300;
  double b = x + 1.0 - a, c = 1.0 / kTiny, d = 1.0 / b, h = d;
  for (int n = 1; n < 1000; ++n) {
    const double an = -n * (n - a);
    b += 2.0;
    d = an * d + b;
    if (std::abs(d) < kTiny) d = kTiny;
    c = b + an / c;
    if (std::abs(c) < kTiny) c = kTiny;
    d = 1.0 / d;
    const double delta = d * c;
    h *= delta;
    if (std::abs(delta - 1.0) < 1e-16) break;
  }
  return h * std::exp(log_prefactor);
}

}  // namespace

double ChiSquareUpperTail(double x, double k) {
  if (x <= 0.0) return 1.0;
  return RegularizedUpperGamma(0.5 * k, 0.5 * x);
}

double ChiSquareQuantile(double p, double k) {
  // The tail falls monotonically in x: bisect between 0 and a bound far past the quantile.
  double low = 0.0, high = k + 10.0 * std::sqrt(2.0 * k) + 100.0;
  while (ChiSquareUpperTail(high, k) > p) high *= 2.0;
  for (int i = 0; i < 200 && high - low > 1e-12 * high; ++i) {
    const double mid = 0.5 * (low + high);
    (ChiSquareUpperTail(mid, k) > p ? low : high) = mid;
  }
  return 0.5 * (low + high);
}

}  // namespace autocal
