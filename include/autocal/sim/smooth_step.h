#pragma once

// The septic smooth step S(x) = 35x^4 - 84x^5 + 70x^6 - 20x^7 on [0, 1]: S(0) = 0, S(1) = 1,
// and its first three derivatives vanish at both ends. Every transition of the simulated
// drive (speed, heading, curvature, road grade) is built from it, so the trajectory is C^3
// at every junction and the simulated IMU signals (which need the second derivative of
// position and the first of attitude) are continuous. Templated on the scalar so that the
// trajectory can be evaluated with derivative-carrying scalars.

namespace autocal {
namespace sim {

// The value of a scalar, used to pick the piece of a piecewise function. Derivative-carrying
// scalar types provide their own overload (found by argument-dependent lookup).
inline double ScalarValue(double x) { return x; }

// S(x), valid for x in [0, 1].
template <typename T>
T SmoothStep(const T& x) {
  const T x2 = x * x;
  return x2 * x2 * (T(35.0) + x * (T(-84.0) + x * (T(70.0) + x * T(-20.0))));
}

// dS/dx = 140 x^3 (1 - x)^3.
template <typename T>
T SmoothStepDerivative(const T& x) {
  const T y = x * (T(1.0) - x);
  return T(140.0) * y * y * y;
}

// Integral of S from 0 to x: 7x^5 - 14x^6 + 10x^7 - 5/2 x^8 (equals 1/2 at x = 1).
template <typename T>
T SmoothStepIntegral(const T& x) {
  const T x2 = x * x;
  return x2 * x2 * x * (T(7.0) + x * (T(-14.0) + x * (T(10.0) + x * T(-2.5))));
}

// Largest |dS/dx| (at x = 1/2): a transition of height h over length L has peak slope
// kSmoothStepPeakSlope * h / L.
constexpr double kSmoothStepPeakSlope = 35.0 / 16.0;

}  // namespace sim
}  // namespace autocal
