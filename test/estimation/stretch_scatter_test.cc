#include "autocal/estimation/stretch_scatter.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "autocal/common/chi_square.h"
#include "autocal/common/error.h"
#include "autocal/estimation/calibration_observability.h"

namespace autocal {
namespace estimation {
namespace {

// Two coordinates, correlated 0.5, variances 4 and 1.
BlockCovariance TwoCoordinates() {
  BlockCovariance c;
  c.ok = true;
  c.matrix = (Eigen::Matrix2d() << 4.0, 1.0, 1.0, 1.0).finished();
  c.offsets = {0};
  return c;
}

// One source over 16 stretches of equal expectation (15 degrees of freedom about their mean):
// its share of coordinate 0 is half the variance, and its stretches scatter `ratio` times their
// expectation along it.
StretchScatter OneSource(double ratio) {
  StretchScatter scatter;
  scatter.ok = true;
  scatter.stretches = 16;
  scatter.offsets = {0};
  scatter.variance = TwoCoordinates().matrix.diagonal();
  StretchScatter::Source source;
  source.name = "wheel";
  source.model = (Eigen::Matrix2d() << 2.0, 0.2, 0.2, 0.3).finished();
  source.expected = 0.8 * source.model;
  source.observed = source.expected;
  source.observed(0, 0) *= ratio;
  source.degrees_of_freedom = Eigen::Vector2d::Constant(15.0);
  scatter.sources.push_back(source);
  return scatter;
}

const Eigen::VectorXd kNoLimit = Eigen::Vector2d::Constant(std::numeric_limits<double>::max());

double Correlation(const Eigen::MatrixXd& c) { return c(0, 1) / std::sqrt(c(0, 0) * c(1, 1)); }

TEST(WidenedForScatter, LeavesAScatterWithinChanceAsItIs) {
  // Chi-square's 99.9 % point over 15 degrees of freedom is 2.51 of them.
  const double limit = ChiSquareQuantile(0.001, 15) / 15.0;
  std::vector<ScatterExcess> excess;
  const BlockCovariance out =
      WidenedForScatter(TwoCoordinates(), OneSource(0.99 * limit), 0.001, kNoLimit, &excess);
  EXPECT_EQ(out.matrix, TwoCoordinates().matrix);
  EXPECT_TRUE(excess.empty());
  // Just above it, widened.
  EXPECT_NE(WidenedForScatter(TwoCoordinates(), OneSource(1.01 * limit), 0.001, kNoLimit).matrix,
            TwoCoordinates().matrix);
}

// A coordinate whose stretches the solve fits almost wholly (expected below 1e-3 of the model)
// is not judged, however its rounding-level scatter compares: neither widened nor recorded.
TEST(WidenedForScatter, LeavesACoordinateTheSolveFitsWhollyUnjudged) {
  StretchScatter scatter = OneSource(100.0);
  StretchScatter::Source& source = scatter.sources[0];
  EXPECT_TRUE(JudgesScatter(source, 0));
  source.expected(0, 0) = 0.999e-3 * source.model(0, 0);
  EXPECT_FALSE(JudgesScatter(source, 0));
  EXPECT_TRUE(JudgesScatter(source, 1));
  EXPECT_EQ(WidenedForScatter(TwoCoordinates(), scatter, 0.001, kNoLimit).matrix,
            TwoCoordinates().matrix);
  source.expected(1, 1) = 0.0;
  EXPECT_FALSE(JudgesScatter(source, 1));
}

// Nine times the expected scatter: the source's share of coordinate 0 (2 of 4) becomes 18, the
// variance 20; the correlation and coordinate 1 stay.
TEST(WidenedForScatter, ScalesTheSourcesShareByItsScatter) {
  std::vector<ScatterExcess> excess;
  const BlockCovariance out =
      WidenedForScatter(TwoCoordinates(), OneSource(9.0), 0.001, kNoLimit, &excess);
  ASSERT_TRUE(out.ok);
  EXPECT_NEAR(out.matrix(0, 0), 20.0, 1e-12);
  EXPECT_NEAR(out.matrix(1, 1), 1.0, 1e-12);
  EXPECT_NEAR(Correlation(out.matrix), Correlation(TwoCoordinates().matrix), 1e-12);
  ASSERT_EQ(excess.size(), 1u);
  EXPECT_EQ(excess[0].source, "wheel");
  EXPECT_EQ(excess[0].coordinate, 0);
  EXPECT_NEAR(excess[0].ratio, 3.0, 1e-12);
  EXPECT_NEAR(excess[0].sigma_factor, std::sqrt(5.0), 1e-12);
  // The share is a fraction of J^T J's variance, applied to the covariance given: with J^T J's
  // twice it (the covariance completed, Eq. C5), a quarter of 4, widened by 8 times, adds 8.
  StretchScatter completed = OneSource(9.0);
  completed.variance *= 2.0;
  EXPECT_NEAR(WidenedForScatter(TwoCoordinates(), completed, 0.001, kNoLimit).matrix(0, 0), 12.0,
              1e-12);
}

TEST(WidenedForScatter, StopsAtTheLimitAndNeverNarrows) {
  const Eigen::Vector2d limit(9.0, 0.5);  // coordinate 1's limit lies below its variance
  std::vector<ScatterExcess> excess;
  const BlockCovariance out =
      WidenedForScatter(TwoCoordinates(), OneSource(9.0), 0.001, limit, &excess);
  EXPECT_NEAR(out.matrix(0, 0), 9.0, 1e-12);
  EXPECT_NEAR(out.matrix(1, 1), 1.0, 1e-12);
  ASSERT_EQ(excess.size(), 1u);
  EXPECT_NEAR(excess[0].sigma_factor, 1.5, 1e-12);
  // Held at its variance by the limit, nothing is widened and nothing reported.
  const BlockCovariance held = WidenedForScatter(TwoCoordinates(), OneSource(9.0), 0.001,
                                                 Eigen::Vector2d(4.0, 1.0), &excess);
  EXPECT_EQ(held.matrix, TwoCoordinates().matrix);
  EXPECT_TRUE(excess.empty());
}

// With one degree of freedom (the drive's information in two stretches) nine times is chance
// (chi-square's 99.9 % point for one is 10.8); so is any ratio where the solve fits the
// stretches almost wholly (expected below a thousandth of the model's share).
TEST(WidenedForScatter, CountsTheDegreesOfFreedomTheStretchesHave) {
  StretchScatter scatter = OneSource(9.0);
  scatter.sources[0].degrees_of_freedom.setOnes();
  EXPECT_EQ(WidenedForScatter(TwoCoordinates(), scatter, 0.001, kNoLimit).matrix,
            TwoCoordinates().matrix);
  StretchScatter fitted = OneSource(9.0);
  fitted.sources[0].expected(0, 0) = 1e-4 * fitted.sources[0].model(0, 0);
  EXPECT_EQ(WidenedForScatter(TwoCoordinates(), fitted, 0.001, kNoLimit).matrix,
            TwoCoordinates().matrix);
}

TEST(WidenedForScatter, PassesAFailedCovarianceOrScatterAndRefusesMismatchedLimits) {
  BlockCovariance failed = TwoCoordinates();
  failed.ok = false;
  EXPECT_FALSE(WidenedForScatter(failed, OneSource(9.0), 0.001, kNoLimit).ok);
  StretchScatter none = OneSource(9.0);
  none.ok = false;
  EXPECT_EQ(WidenedForScatter(TwoCoordinates(), none, 0.001, kNoLimit).matrix,
            TwoCoordinates().matrix);
  EXPECT_THROW(WidenedForScatter(TwoCoordinates(), OneSource(9.0), 0.001, Eigen::Vector3d::Ones()),
               Error);
}

}  // namespace
}  // namespace estimation
}  // namespace autocal
