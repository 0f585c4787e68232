#include "autocal/estimation/increment_scatter.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <iostream>
#include <random>

#include "autocal/common/chi_square.h"
#include "autocal/common/error.h"
#include "autocal/geometry/so3.h"

namespace autocal {
namespace estimation {
namespace {

// A Bayesian filter of a constant lever arm p_I_A (prior N(0, 0.3^2 I)) from 1600 scalar
// readings y = h^T p + e, weighed with sigma 0.01 while e has sigma 0.01 * noise_factor; a
// checkpoint after each 50 readings (32, the last at the end, as the online estimator's
// default). `jump` is added to the estimate at the first four checkpoints (an estimate
// settling from its start).
struct Filtered {
  std::vector<CalibrationCheckpoint> checkpoints;
  Eigen::Vector3d truth;
};

Filtered Filter(double noise_factor, uint32_t seed, double jump = 0.0) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> normal;
  Filtered out;
  for (int i = 0; i < 3; ++i) out.truth(i) = 0.3 * normal(rng);
  const double sigma = 0.01;
  Eigen::Matrix3d information = Eigen::Matrix3d::Identity() / (0.3 * 0.3);
  Eigen::Vector3d vector = Eigen::Vector3d::Zero();
  for (int t = 1; t <= 1600; ++t) {
    const Eigen::Vector3d h(normal(rng), normal(rng), normal(rng));
    const double y = h.dot(out.truth) + noise_factor * sigma * normal(rng);
    information += h * h.transpose() / (sigma * sigma);
    vector += h * y / (sigma * sigma);
    if (t % 50 != 0) continue;
    CalibrationCheckpoint checkpoint;
    checkpoint.covariance.names = {"p_I_A"};
    checkpoint.covariance.offsets = {0};
    checkpoint.covariance.covariance = information.inverse();
    checkpoint.value.p_I_A = information.ldlt().solve(vector);
    if (t <= 200) checkpoint.value.p_I_A += Eigen::Vector3d::Constant(jump * t / 200.0);
    out.checkpoints.push_back(checkpoint);
  }
  return out;
}

TEST(OrderStatisticQuantile, OneDrawIsChiSquaresQuantile) {
  EXPECT_NEAR(internal::OrderStatisticQuantile(1, 1, 0.05), ChiSquareQuantile(0.05, 1), 1e-9);
  EXPECT_NEAR(internal::OrderStatisticQuantile(1, 1, 0.5), 0.454936, 1e-6);
}

// A long stream's many steps: the median of 3001 draws stays near chi^2(1)'s median (its
// binomial terms would overflow a double), and the arguments are checked.
TEST(OrderStatisticQuantile, ManyDrawsAndItsArguments) {
  const double median = internal::OrderStatisticQuantile(1501, 3001, 0.5);
  const double gate = internal::OrderStatisticQuantile(1501, 3001, 0.001);
  EXPECT_NEAR(median, 0.454936, 1e-3);
  EXPECT_GT(gate, median);
  EXPECT_LT(gate, 1.2 * median);
  EXPECT_THROW(internal::OrderStatisticQuantile(0, 3, 0.5), Error);
  EXPECT_THROW(internal::OrderStatisticQuantile(4, 3, 0.5), Error);
  EXPECT_THROW(internal::OrderStatisticQuantile(2, 3, 1.0), Error);
}

// The median of 15 chi^2(1) draws exceeds its 1 % point in 1 % of 20000 trials.
TEST(OrderStatisticQuantile, MatchesDrawsOfTheMedian) {
  std::mt19937 rng(3);
  std::chi_squared_distribution<double> chi_square(1.0);
  const double q = internal::OrderStatisticQuantile(8, 15, 0.01);
  int beyond = 0;
  const int trials = 20000;
  for (int t = 0; t < trials; ++t) {
    std::vector<double> draws(15);
    for (double& d : draws) d = chi_square(rng);
    std::nth_element(draws.begin(), draws.begin() + 7, draws.end());
    beyond += draws[7] > q;
  }
  // Binomial sigma: 0.07 % of the trials.
  EXPECT_NEAR(beyond / static_cast<double>(trials), 0.01, 0.0025);
}

// Steps as the covariance says: the ratio is about 1 and exceeds chance about as often as
// the significance says.
TEST(IncrementScatter, StepsAsPredictedAreChance) {
  std::vector<double> ratios;
  int exceeding = 0;
  for (uint32_t seed = 0; seed < 300; ++seed) {
    const IncrementScatter scatter = ScatterOfIncrements(Filter(1.0, seed).checkpoints, 0.01);
    ASSERT_EQ(scatter.directions.size(), 3u);
    for (const IncrementScatter::Direction& d : scatter.directions) {
      EXPECT_EQ(d.steps, 31);
      ratios.push_back(d.ratio);
      exceeding += d.exceeds;
    }
  }
  std::nth_element(ratios.begin(), ratios.begin() + 450, ratios.end());
  std::cout << "median ratio " << ratios[450] << ", " << exceeding << " of 900 exceed chance\n";
  EXPECT_NEAR(ratios[450], 1.0, 0.1);  // median-unbiased
  // 1 % of 900 directions: 9, binomial sigma 3.
  EXPECT_LE(exceeding, 20);
}

// Readings three times noisier than weighed: the steps' variance is about 9 times the
// predicted, the sigmas are widened about 3 times, and the widened ones cover the errors
// (measured: their normalized squared error averages 1.24, the filter's own 8.6).
TEST(IncrementScatter, NoisierReadingsWidenTheirSigmas) {
  double nees_as_filtered = 0.0, nees_widened = 0.0;
  int exceeding = 0;
  std::vector<double> ratios;
  const int drives = 200;
  for (uint32_t seed = 0; seed < static_cast<uint32_t>(drives); ++seed) {
    const Filtered filtered = Filter(3.0, seed);
    const IncrementScatter scatter = ScatterOfIncrements(filtered.checkpoints, 0.001);
    const CalibrationCovariance& last = filtered.checkpoints.back().covariance;
    const CalibrationCovariance widened =
        WidenedForIncrements(last, scatter, Eigen::Vector3d::Constant(0.3 * 0.3), nullptr);
    const Eigen::Vector3d error = filtered.checkpoints.back().value.p_I_A - filtered.truth;
    for (int i = 0; i < 3; ++i) {
      nees_as_filtered += error(i) * error(i) / last.covariance(i, i);
      nees_widened += error(i) * error(i) / widened.covariance(i, i);
    }
    for (const IncrementScatter::Direction& d : scatter.directions) {
      ratios.push_back(d.ratio);
      exceeding += d.exceeds;
    }
  }
  nees_as_filtered /= 3 * drives;
  nees_widened /= 3 * drives;
  std::nth_element(ratios.begin(), ratios.begin() + 300, ratios.end());
  std::cout << "median ratio " << ratios[300] << ", " << exceeding << " of " << 3 * drives
            << " exceed chance; ANEES " << nees_as_filtered << " as filtered, " << nees_widened
            << " widened\n";
  EXPECT_NEAR(ratios[300], 9.0, 1.0);
  EXPECT_GT(exceeding, 0.95 * 3 * drives);
  EXPECT_NEAR(nees_as_filtered, 9.0, 1.5);
  // A factor estimated from 31 steps: 1/ratio averages above 1/9, and 2 % stay within chance.
  EXPECT_GT(nees_widened, 0.8);
  EXPECT_LT(nees_widened, 1.5);
}

// Four large steps while the estimate settles are not the steps' typical scatter: nothing is
// widened.
TEST(IncrementScatter, ASettlingStartIsNotScatter) {
  const Filtered filtered = Filter(1.0, 5, 0.05);
  const IncrementScatter scatter = ScatterOfIncrements(filtered.checkpoints, 0.001);
  ASSERT_EQ(scatter.directions.size(), 3u);
  for (const IncrementScatter::Direction& d : scatter.directions) {
    EXPECT_FALSE(d.exceeds);
    EXPECT_LT(d.ratio, 3.0);
  }
  // The jump is there: 1.25 cm a step against the second step's predicted sigma.
  const double predicted = filtered.checkpoints[1].covariance.covariance(0, 0) -
                           filtered.checkpoints[2].covariance.covariance(0, 0);
  EXPECT_GT(0.0125 / std::sqrt(predicted), 20.0);
}

// A rotation's steps are taken on its manifold: the mount turning 3 predicted sigmas about
// its x axis at every step (and not at all about y and z) reads 9 / chance's median there.
// A step whose predicted variance is not positive, or below a quarter of an even share of the
// final variance (1e-6 / 60 here), is left out.
TEST(IncrementScatter, RotationStepsOnTheManifold) {
  std::vector<CalibrationCheckpoint> checkpoints;
  const double step_rad = 3e-3;
  for (int j = 0; j < 16; ++j) {
    CalibrationCheckpoint c;
    c.covariance.names = {"q_I_V"};
    c.covariance.offsets = {0};
    c.covariance.covariance = Eigen::Matrix3d::Identity() * (16 - j) * 1e-6;
    // The step to checkpoint 3 predicts nothing in x (left out), the next one predicts twice.
    if (j == 3) c.covariance.covariance(0, 0) = 14e-6;
    // The step to checkpoint 8 predicts 1e-8 (left out), the next one nearly twice.
    if (j == 8) c.covariance.covariance(0, 0) = 9e-6 - 1e-8;
    c.value.q_I_V = geometry::Exp(Eigen::Vector3d(0.2, -0.1, 0.4)) *
                    geometry::Exp(Eigen::Vector3d(step_rad * j, 0.0, 0.0));
    checkpoints.push_back(c);
  }
  const IncrementScatter scatter = ScatterOfIncrements(checkpoints, 0.001);
  ASSERT_EQ(scatter.directions.size(), 3u);
  const IncrementScatter::Direction& x = scatter.directions[0];
  EXPECT_EQ(x.block, "q_I_V");
  EXPECT_EQ(x.row, 0);
  EXPECT_EQ(x.steps, 13);  // 11 squares of 9 and two of about 4.5: the 7th smallest is 9
  EXPECT_NEAR(x.ratio, 9.0 / internal::OrderStatisticQuantile(7, 13, 0.5), 1e-6);
  EXPECT_TRUE(x.exceeds);
  EXPECT_EQ(scatter.directions[1].steps, 15);
  EXPECT_LT(scatter.directions[1].ratio, 1e-12);
  EXPECT_FALSE(scatter.directions[1].exceeds);
}

// The widening keeps the correlations (D C D), never narrows, stops at the limit, and names
// what it widened.
TEST(IncrementScatter, WideningKeepsCorrelationsAndStopsAtTheLimit) {
  CalibrationCovariance covariance;
  covariance.names = {"p_I_A"};
  covariance.offsets = {0};
  covariance.covariance = Eigen::Matrix3d::Identity() * 1e-4;
  covariance.covariance(0, 1) = covariance.covariance(1, 0) = 5e-5;
  IncrementScatter scatter;
  scatter.directions = {
      {"p_I_A", 0, 15, 4.0, true}, {"p_I_A", 1, 15, 100.0, true}, {"p_I_A", 2, 15, 50.0, false}};
  std::vector<WidenedDirection> widened;
  const CalibrationCovariance out =
      WidenedForIncrements(covariance, scatter, Eigen::Vector3d(1.0, 9e-4, 1.0), &widened);
  EXPECT_NEAR(out.covariance(0, 0), 4e-4, 1e-15);
  EXPECT_NEAR(out.covariance(1, 1), 9e-4, 1e-15);  // at the limit, not 100 times
  EXPECT_NEAR(out.covariance(2, 2), 1e-4, 1e-15);  // within chance: as it was
  EXPECT_NEAR(out.covariance(0, 1), 5e-5 * 2.0 * 3.0, 1e-15);
  ASSERT_EQ(widened.size(), 2u);
  EXPECT_EQ(widened[0].direction.row, 1);
  EXPECT_NEAR(widened[0].sigma_factor, 3.0, 1e-12);
  EXPECT_NEAR(widened[1].sigma_factor, 2.0, 1e-12);
  EXPECT_THROW(WidenedForIncrements(covariance, scatter, Eigen::Vector2d::Ones(), nullptr), Error);
  EXPECT_THROW(ScatterOfIncrements({}, 0.0), Error);
  EXPECT_TRUE(ScatterOfIncrements({CalibrationCheckpoint()}, 0.01).directions.empty());
}

}  // namespace
}  // namespace estimation
}  // namespace autocal
