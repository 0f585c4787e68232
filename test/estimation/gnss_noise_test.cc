// GNSS noise from the residuals (estimation/gnss_noise.h, Eq. N2): per axis group, the rows'
// robust sigma, used as the scale from kMinGnssNoiseScale and kMinGnssNoiseRows on.
#include "autocal/estimation/gnss_noise.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/running_median.h"

namespace autocal {
namespace estimation {
namespace {

// n rows of a fix's east, north and up errors with sigmas h, h, v, whitened by a stated 1.
GnssRowScatter Fixes(size_t n, double h, double v, std::mt19937_64* random) {
  std::normal_distribution<double> normal(0.0, 1.0);
  GnssRowScatter scatter;
  for (size_t i = 0; i < n; ++i) {
    scatter.AddHorizontal(h * normal(*random));
    scatter.AddHorizontal(h * normal(*random));
    scatter.AddVertical(v * normal(*random));
  }
  return scatter;
}

TEST(RunningMedian, IsTheUpperMiddleElementAtEveryCount) {
  std::mt19937_64 random(2);
  std::uniform_real_distribution<double> uniform(-5.0, 5.0);
  RunningMedian running;
  std::vector<double> values;
  for (int i = 0; i < 500; ++i) {
    values.push_back(i % 7 == 0 ? 1.0 : uniform(random));  // ties too
    running.Add(values.back());
    std::vector<double> sorted = values;
    std::sort(sorted.begin(), sorted.end());
    ASSERT_EQ(running.size(), values.size());
    ASSERT_EQ(running.Median(), sorted[sorted.size() / 2]) << i;
  }
}

TEST(GnssRowScatter, KeepsTheStatedStdWhenTheRowsScatterAsStated) {
  std::mt19937_64 random(3);
  const GnssNoiseFromResiduals noise = Fixes(1000, 1.0, 1.0, &random).Noise();
  EXPECT_EQ(noise.horizontal.rows, 2000u);
  EXPECT_EQ(noise.vertical.rows, 1000u);
  EXPECT_NEAR(noise.horizontal.robust_sigma, 1.0, 0.05);
  EXPECT_NEAR(noise.vertical.robust_sigma, 1.0, 0.07);
  EXPECT_TRUE(noise.Scale().IsOne());
}

// Fixes four times noisier than stated, one row in fifty a multipath jump of 50 stated sigmas:
// each group's scale is its Gaussian part's (the jumps move the median by 2 %).
TEST(GnssRowScatter, ScalesByTheScatterTheRowsShowWhateverTheOutliers) {
  std::mt19937_64 random(4);
  std::normal_distribution<double> normal(0.0, 4.0);
  GnssRowScatter scatter;
  for (int i = 0; i < 3000; ++i) {
    const bool jump = i % 50 == 0;
    scatter.AddHorizontal(jump ? 50.0 : normal(random));
    scatter.AddVertical(jump ? -50.0 : normal(random));
  }
  const GnssNoiseFromResiduals noise = scatter.Noise();
  EXPECT_NEAR(noise.horizontal.scale, 4.0, 0.3);
  EXPECT_NEAR(noise.vertical.scale, 4.0, 0.3);
  EXPECT_EQ(noise.horizontal.scale, noise.horizontal.robust_sigma);
}

// A receiver whose vertical std alone is stated four times too small: only the vertical rows
// are scaled (one scale over all rows would read 1.4, below the threshold: their median lies
// among the horizontal two thirds).
TEST(GnssRowScatter, ScalesEachAxisGroupOnItsOwn) {
  std::mt19937_64 random(5);
  const GnssNoiseFromResiduals noise = Fixes(1000, 1.0, 4.0, &random).Noise();
  EXPECT_EQ(noise.horizontal.scale, 1.0);
  EXPECT_NEAR(noise.vertical.scale, 4.0, 0.3);
  const GnssStdScale scale = noise.Scale();
  const Eigen::Vector3d sigma = scale.Applied(Eigen::Vector3d(0.5, 0.6, 1.0));
  EXPECT_EQ(sigma.head<2>(), Eigen::Vector2d(0.5, 0.6));
  EXPECT_EQ(sigma.z(), noise.vertical.scale);
}

TEST(GnssRowScatter, TooFewRowsBelowThresholdAndNonFiniteRowsKeepTheStatedStd) {
  std::mt19937_64 random(6);
  const GnssNoiseFromResiduals below = Fixes(1000, 1.3, 1.3, &random).Noise();
  EXPECT_NEAR(below.horizontal.robust_sigma, 1.3, 0.07);
  EXPECT_TRUE(below.Scale().IsOne());
  // Rows ten times noisier than stated, the vertical ones one short of the fewest judged (the
  // horizontal ones, two per fix, are judged).
  GnssRowScatter few = Fixes(kMinGnssNoiseRows - 1, 10.0, 10.0, &random);
  EXPECT_GT(few.Noise().vertical.robust_sigma, 5.0);
  EXPECT_EQ(few.Noise().vertical.scale, 1.0);
  EXPECT_GT(few.Noise().horizontal.scale, 5.0);
  EXPECT_TRUE(few.AddVertical(10.0));
  EXPECT_GT(few.Noise().vertical.scale, 5.0);
  EXPECT_FALSE(few.AddVertical(std::numeric_limits<double>::quiet_NaN()));
  EXPECT_FALSE(few.AddHorizontal(std::numeric_limits<double>::infinity()));
  EXPECT_EQ(few.Noise().vertical.rows, kMinGnssNoiseRows);
  EXPECT_TRUE(GnssRowScatter().Noise().Scale().IsOne());
  EXPECT_THROW((GnssStdScale{0.0, 1.0}.Check("test")), Error);
  EXPECT_THROW((GnssStdScale{1.0, std::nan("")}.Check("test")), Error);
  EXPECT_NO_THROW((GnssStdScale{2.0, 1.0}.Check("test")));
}

// kMinGnssNoiseRows' derivation, exactly: the chance that rows as stated put the upper median
// of |r| at or above 1.5 / 1.4826 is the binomial tail P(B(n, q) >= n - n/2); under 0.001 from
// 67 rows on (to 400 here), not at 66.
TEST(GnssRowScatter, TheFewestRowsJudgedRarelyScaleByChance) {
  const double q = std::erfc(kMinGnssNoiseScale / 1.4826 / std::sqrt(2.0));
  const auto tail = [q](size_t n) {
    double sum = 0.0;
    for (size_t j = n - n / 2; j <= n; ++j) {
      const double log_term = std::lgamma(n + 1.0) - std::lgamma(j + 1.0) -
                              std::lgamma(n - j + 1.0) + j * std::log(q) + (n - j) * std::log1p(-q);
      sum += std::exp(log_term);
    }
    return sum;
  };
  EXPECT_GE(tail(kMinGnssNoiseRows - 1), 0.001);
  for (size_t n = kMinGnssNoiseRows; n <= 400; ++n) EXPECT_LT(tail(n), 0.001) << n;
  // The estimator follows that model: 20 000 streams of that many rows as stated.
  std::mt19937_64 random(7);
  std::normal_distribution<double> normal(0.0, 1.0);
  int scaled = 0;
  constexpr int kDraws = 20000;
  for (int d = 0; d < kDraws; ++d) {
    GnssRowScatter scatter;
    for (size_t i = 0; i < kMinGnssNoiseRows; ++i) scatter.AddVertical(normal(random));
    scaled += scatter.Noise().vertical.scale > 1.0;
  }
  const double expected = kDraws * tail(kMinGnssNoiseRows);  // 13
  EXPECT_LT(std::abs(scaled - expected), 4.0 * std::sqrt(expected)) << scaled;
}

}  // namespace
}  // namespace estimation
}  // namespace autocal
