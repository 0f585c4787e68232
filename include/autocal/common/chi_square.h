#pragma once

// The chi-square distribution's upper tail, for tests of agreement (a sum of k squared
// standard normal variables exceeds x with probability Q(k/2, x/2), the regularized upper
// incomplete gamma function).

namespace autocal {

// P(chi^2_k > x) for k > 0 degrees of freedom, not necessarily whole (an effective count, as
// Satterthwaite's), and x >= 0; 1 for x <= 0.
double ChiSquareUpperTail(double x, double k);

// The x with P(chi^2_k > x) = p, for 0 < p < 1 (the 99 % quantile is p = 0.01).
double ChiSquareQuantile(double p, double k);

}  // namespace autocal
