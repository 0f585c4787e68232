#pragma once

// A scalar that carries a value and its first two time derivatives (a truncated Taylor
// series, forward-mode automatic differentiation of order two). Evaluating the trajectory
// with Taylor2 time gives position, velocity and acceleration, and R with dR/dt, exactly to
// rounding: the simulated IMU is the analytic derivative of the ground truth.
//
// For y = f(x) with x = (x0, x1, x2): y1 = f'(x0) x1, y2 = f''(x0) x1^2 + f'(x0) x2.

#include <Eigen/Core>
#include <cmath>

namespace autocal {
namespace sim {

struct Taylor2 {
  double v = 0.0;   // value
  double d1 = 0.0;  // first derivative
  double d2 = 0.0;  // second derivative

  Taylor2() = default;
  // Implicit on purpose: constants mix freely with variables, as with Eigen's scalars.
  Taylor2(double value) : v(value) {}  // NOLINT(runtime/explicit)
  Taylor2(double value, double first, double second) : v(value), d1(first), d2(second) {}

  static Taylor2 Variable(double value) { return Taylor2(value, 1.0, 0.0); }

  Taylor2& operator+=(const Taylor2& b) {
    v += b.v;
    d1 += b.d1;
    d2 += b.d2;
    return *this;
  }
  Taylor2& operator-=(const Taylor2& b) {
    v -= b.v;
    d1 -= b.d1;
    d2 -= b.d2;
    return *this;
  }
  Taylor2& operator*=(const Taylor2& b) {
    *this = Taylor2(v * b.v, d1 * b.v + v * b.d1, d2 * b.v + 2.0 * d1 * b.d1 + v * b.d2);
    return *this;
  }
  Taylor2& operator/=(const Taylor2& b) {
    const double q = v / b.v;
    const double q1 = (d1 - q * b.d1) / b.v;
    const double q2 = (d2 - 2.0 * q1 * b.d1 - q * b.d2) / b.v;
    *this = Taylor2(q, q1, q2);
    return *this;
  }
};

inline Taylor2 operator-(const Taylor2& a) { return Taylor2(-a.v, -a.d1, -a.d2); }
inline Taylor2 operator+(Taylor2 a, const Taylor2& b) { return a += b; }
inline Taylor2 operator-(Taylor2 a, const Taylor2& b) { return a -= b; }
inline Taylor2 operator*(Taylor2 a, const Taylor2& b) { return a *= b; }
inline Taylor2 operator/(Taylor2 a, const Taylor2& b) { return a /= b; }
inline bool operator<(const Taylor2& a, const Taylor2& b) { return a.v < b.v; }
inline bool operator>(const Taylor2& a, const Taylor2& b) { return a.v > b.v; }
inline bool operator==(const Taylor2& a, const Taylor2& b) {
  return a.v == b.v && a.d1 == b.d1 && a.d2 == b.d2;
}
inline bool operator!=(const Taylor2& a, const Taylor2& b) { return !(a == b); }

// Applies f with f(x0) = f0, f'(x0) = f1, f''(x0) = f2 (the chain rule above).
inline Taylor2 Chain(const Taylor2& x, double f0, double f1, double f2) {
  return Taylor2(f0, f1 * x.d1, f2 * x.d1 * x.d1 + f1 * x.d2);
}

inline Taylor2 sin(const Taylor2& x) {
  const double s = std::sin(x.v), c = std::cos(x.v);
  return Chain(x, s, c, -s);
}
inline Taylor2 cos(const Taylor2& x) {
  const double s = std::sin(x.v), c = std::cos(x.v);
  return Chain(x, c, -s, -c);
}
inline Taylor2 sqrt(const Taylor2& x) {
  const double r = std::sqrt(x.v);
  return Chain(x, r, 0.5 / r, -0.25 / (r * x.v));
}

inline double ScalarValue(const Taylor2& x) { return x.v; }

}  // namespace sim
}  // namespace autocal

namespace Eigen {
template <>
struct NumTraits<autocal::sim::Taylor2> : NumTraits<double> {
  using Real = autocal::sim::Taylor2;
  using NonInteger = autocal::sim::Taylor2;
  using Nested = autocal::sim::Taylor2;
  using Literal = autocal::sim::Taylor2;
  enum {
    IsComplex = 0,
    IsInteger = 0,
    IsSigned = 1,
    RequireInitialization = 1,
    ReadCost = 3,
    AddCost = 3,
    MulCost = 9
  };
};
}  // namespace Eigen
