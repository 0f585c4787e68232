#include "autocal/common/chi_square.h"

#include <gtest/gtest.h>

#include <cmath>

namespace autocal {
namespace {

// Closed forms: k = 2 gives exp(-x/2); k = 1 gives erfc(sqrt(x/2)).
TEST(ChiSquare, UpperTailMatchesClosedForms) {
  for (double x : {0.01, 0.5, 1.0, 2.0, 3.0, 5.0, 10.0, 30.0, 80.0}) {
    EXPECT_NEAR(ChiSquareUpperTail(x, 2), std::exp(-0.5 * x), 1e-14) << x;
    EXPECT_NEAR(ChiSquareUpperTail(x, 1), std::erfc(std::sqrt(0.5 * x)), 1e-14) << x;
  }
  EXPECT_EQ(ChiSquareUpperTail(0.0, 3), 1.0);
}

// Effective degrees of freedom need not be whole: Q(a + 1, y) = Q(a, y) + y^a e^-y / Gamma(a + 1)
// links k and k + 2, and the tail falls between those of the whole counts around k.
TEST(ChiSquare, UpperTailTakesFractionalDegreesOfFreedom) {
  for (double k : {0.5, 1.9, 6.6}) {
    for (double x : {0.3, 2.0, 7.0, 20.0}) {
      const double y = 0.5 * x, a = 0.5 * k;
      EXPECT_NEAR(ChiSquareUpperTail(x, k + 2.0) - ChiSquareUpperTail(x, k),
                  std::exp(a * std::log(y) - y - std::lgamma(a + 1.0)), 1e-13)
          << k << " " << x;
    }
  }
  EXPECT_GT(ChiSquareUpperTail(10.0, 1.9), ChiSquareUpperTail(10.0, 1));
  EXPECT_LT(ChiSquareUpperTail(10.0, 1.9), ChiSquareUpperTail(10.0, 2));
  EXPECT_LT(ChiSquareQuantile(0.001, 1.9), ChiSquareQuantile(0.001, 2));
  EXPECT_GT(ChiSquareQuantile(0.001, 1.9), ChiSquareQuantile(0.001, 1));
}

// Tabulated 99 % and 95 % quantiles (NIST/SEMATECH e-Handbook, Table 1.3.6.7.4).
TEST(ChiSquare, QuantilesMatchTables) {
  EXPECT_NEAR(ChiSquareQuantile(0.01, 1), 6.635, 1e-3);
  EXPECT_NEAR(ChiSquareQuantile(0.01, 3), 11.345, 1e-3);
  EXPECT_NEAR(ChiSquareQuantile(0.01, 6), 16.812, 1e-3);
  EXPECT_NEAR(ChiSquareQuantile(0.05, 10), 18.307, 1e-3);
  EXPECT_NEAR(ChiSquareQuantile(0.01, 30), 50.892, 1e-3);
  EXPECT_NEAR(ChiSquareQuantile(0.01, 100), 135.807, 1e-3);
}

TEST(ChiSquare, QuantileInvertsTheTail) {
  for (double k : {1.0, 1.9, 2.0, 5.0, 6.6, 17.0, 60.0}) {
    for (double p : {0.9, 0.5, 0.05, 1e-4}) {
      EXPECT_NEAR(ChiSquareUpperTail(ChiSquareQuantile(p, k), k), p, 1e-9 * (1 + p))
          << k << " " << p;
    }
  }
}

}  // namespace
}  // namespace autocal
