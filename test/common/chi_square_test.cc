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
  for (int k : {1, 2, 5, 17, 60}) {
    for (double p : {0.9, 0.5, 0.05, 1e-4}) {
      EXPECT_NEAR(ChiSquareUpperTail(ChiSquareQuantile(p, k), k), p, 1e-9 * (1 + p))
          << k << " " << p;
    }
  }
}

}  // namespace
}  // namespace autocal
