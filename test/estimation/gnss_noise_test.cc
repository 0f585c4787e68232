// GNSS noise from the residuals (estimation/gnss_noise.h, Eq. N2): the rows' robust sigma,
// used as the scale from kMinGnssNoiseScale on.
#include "autocal/estimation/gnss_noise.h"

#include <gtest/gtest.h>

#include <random>
#include <vector>

namespace autocal {
namespace estimation {
namespace {

std::vector<double> GaussianRows(size_t n, double sigma, std::mt19937_64* random) {
  std::normal_distribution<double> normal(0.0, sigma);
  std::vector<double> rows(n);
  for (double& r : rows) r = normal(*random);
  return rows;
}

TEST(GnssNoiseOfRows, KeepsTheStatedStdWhenTheRowsScatterAsStated) {
  std::mt19937_64 random(3);
  const GnssNoiseFromResiduals noise = GnssNoiseOfRows(GaussianRows(3000, 1.0, &random));
  EXPECT_EQ(noise.rows, 3000u);
  EXPECT_NEAR(noise.robust_sigma, 1.0, 0.05);
  EXPECT_EQ(noise.scale, 1.0);
}

// Fixes four times noisier than stated, one row in fifty a multipath jump of 50 stated sigmas:
// the scale is the Gaussian part's (the jumps move the median by 2 %).
TEST(GnssNoiseOfRows, ScalesByTheScatterTheRowsShowWhateverTheOutliers) {
  std::mt19937_64 random(4);
  std::vector<double> rows = GaussianRows(3000, 4.0, &random);
  for (size_t i = 0; i < rows.size(); i += 50) rows[i] = (i % 100 == 0 ? 50.0 : -50.0);
  const GnssNoiseFromResiduals noise = GnssNoiseOfRows(rows);
  EXPECT_NEAR(noise.scale, 4.0, 0.3);
  EXPECT_EQ(noise.scale, noise.robust_sigma);
}

TEST(GnssNoiseOfRows, ABelowThresholdScatterAndNoRowsKeepTheStatedStd) {
  std::mt19937_64 random(5);
  const GnssNoiseFromResiduals below = GnssNoiseOfRows(GaussianRows(3000, 1.3, &random));
  EXPECT_NEAR(below.robust_sigma, 1.3, 0.07);
  EXPECT_EQ(below.scale, 1.0);
  const GnssNoiseFromResiduals none = GnssNoiseOfRows({});
  EXPECT_EQ(none.rows, 0u);
  EXPECT_EQ(none.scale, 1.0);
}

// kMinGnssNoiseRows' derivation: with that many rows as stated the scale is taken by chance
// under once in a thousand (the binomial tail: 0.00065), and rows at the threshold read above
// it about half the time.
TEST(GnssNoiseOfRows, TheFewestRowsAStreamDecidesOnRarelyScaleByChance) {
  std::mt19937_64 random(6);
  constexpr int kDraws = 20000;
  int as_stated_scaled = 0;
  int at_threshold_scaled = 0;
  for (int d = 0; d < kDraws; ++d) {
    as_stated_scaled += GnssNoiseOfRows(GaussianRows(kMinGnssNoiseRows, 1.0, &random)).scale > 1.0;
    at_threshold_scaled +=
        GnssNoiseOfRows(GaussianRows(kMinGnssNoiseRows, kMinGnssNoiseScale, &random)).scale > 1.0;
  }
  EXPECT_LT(as_stated_scaled, kDraws / 1000 + 10);  // 0.001 and the draws' chance
  EXPECT_GT(at_threshold_scaled, kDraws * 4 / 10);
  EXPECT_LT(at_threshold_scaled, kDraws * 6 / 10);
}

}  // namespace
}  // namespace estimation
}  // namespace autocal
