#include "estimation/time_shifted_series.h"

#include <ceres/jet.h>
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "autocal/common/error.h"

namespace autocal {
namespace estimation {
namespace {

using internal::TimeShiftedSeries;
using Jet = ceres::Jet<double, 1>;

constexpr int64_t kStartNs = 1'700'000'000'000'000'000;

// x(t) = (3 + 2 t, -t^2) sampled at irregular stamps (seconds after kStartNs).
TimeShiftedSeries<2> Series(const std::vector<double>& t_s) {
  std::vector<int64_t> t_ns;
  std::vector<Eigen::Vector2d> values;
  for (double t : t_s) {
    t_ns.push_back(kStartNs + static_cast<int64_t>(std::llround(t * 1e9)));
    values.emplace_back(3.0 + 2.0 * t, -t * t);
  }
  return TimeShiftedSeries<2>(t_ns, values, "test series");
}

TEST(TimeShiftedSeries, ReadsTheSensorClockAtImuTimeMinusTheOffset) {
  const TimeShiftedSeries<2> series = Series({0.0, 0.1, 0.25, 0.3, 0.7});
  // IMU time 0.55 s with offset +0.4 s is sensor time 0.15 s: between 0.1 and 0.25.
  const Eigen::Vector2d x = series.At(kStartNs + 550'000'000, 0.4);
  EXPECT_NEAR(x.x(), 3.0 + 2.0 * 0.15, 1e-12);  // linear: exact
  const double s = (0.15 - 0.1) / 0.15;
  EXPECT_NEAR(x.y(), -(1.0 - s) * 0.01 - s * 0.0625, 1e-12);
  // A negative offset reads later sensor samples.
  EXPECT_NEAR(series.At(kStartNs + 100'000'000, -0.4).x(), 3.0 + 2.0 * 0.5, 1e-12);
}

TEST(TimeShiftedSeries, OffsetDerivativeIsMinusTheSegmentSlope) {
  const TimeShiftedSeries<2> series = Series({0.0, 0.1, 0.25, 0.3, 0.7});
  const Jet offset(0.4, 0);
  const Eigen::Matrix<Jet, 2, 1> x = series.At(kStartNs + 550'000'000, offset);
  EXPECT_NEAR(x.x().v[0], -2.0, 1e-9);
  EXPECT_NEAR(x.y().v[0], -(-0.0625 + 0.01) / 0.15, 1e-9);
  // Central difference of the double version inside the same segment agrees.
  const double h = 1e-6;
  const double numeric = (series.At(kStartNs + 550'000'000, 0.4 + h).y() -
                          series.At(kStartNs + 550'000'000, 0.4 - h).y()) /
                         (2.0 * h);
  EXPECT_NEAR(x.y().v[0], numeric, 1e-6);
}

TEST(TimeShiftedSeries, HoldsTheEndValuesOutsideTheSamplesWithoutSlope) {
  const TimeShiftedSeries<2> series = Series({0.0, 0.1, 0.2});
  const Eigen::Matrix<Jet, 2, 1> before = series.At(kStartNs, Jet(0.5, 0));
  EXPECT_DOUBLE_EQ(before.x().a, 3.0);
  EXPECT_DOUBLE_EQ(before.x().v[0], 0.0);
  const Eigen::Matrix<Jet, 2, 1> after = series.At(kStartNs, Jet(-0.5, 0));
  EXPECT_DOUBLE_EQ(after.x().a, 3.4);
  EXPECT_DOUBLE_EQ(after.x().v[0], 0.0);
}

TEST(TimeShiftedSeries, BracketSpanIsTheGapAroundTheShiftedInstant) {
  const TimeShiftedSeries<2> series = Series({0.0, 0.1, 0.5, 0.6});
  EXPECT_NEAR(series.BracketSpanS(kStartNs + 300'000'000, 0.0), 0.4, 1e-12);
  EXPECT_NEAR(series.BracketSpanS(kStartNs + 300'000'000, 0.25), 0.1, 1e-12);
  EXPECT_EQ(series.BracketSpanS(kStartNs + 500'000'000, 0.0), 0.0);
  EXPECT_TRUE(std::isinf(series.BracketSpanS(kStartNs + 900'000'000, 0.0)));
  EXPECT_TRUE(std::isinf(series.BracketSpanS(kStartNs, 0.01)));
}

TEST(TimeShiftedSeries, RejectsStampsThatDoNotIncreaseAndTooFewSamples) {
  try {
    Series({0.0, 0.2, 0.2});
    FAIL() << "equal stamps accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("test series stamps must increase: sample 2"),
              std::string::npos)
        << e.what();
  }
  EXPECT_THROW(Series({0.0}), Error);
}

}  // namespace
}  // namespace estimation
}  // namespace autocal
