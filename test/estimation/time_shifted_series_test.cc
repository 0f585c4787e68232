#include "estimation/time_shifted_series.h"

#include <ceres/jet.h>
#include <gtest/gtest.h>

#include <cmath>
#include <random>
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

// Eq. K9b: the offset's derivative is minus the slope of the least-squares line through the
// samples within kSlopeHalfWidthS of the segment's middle, at least two on each side: for the
// segment (0.1, 0.25) the samples at 0, 0.1, 0.25 and 0.3 s. Exact for the linear component.
TEST(TimeShiftedSeries, OffsetDerivativeIsMinusTheLocalLineSlope) {
  const TimeShiftedSeries<2> series = Series({0.0, 0.1, 0.25, 0.3, 0.7});
  const Jet offset(0.4, 0);
  const Eigen::Matrix<Jet, 2, 1> x = series.At(kStartNs + 550'000'000, offset);
  EXPECT_NEAR(x.x().v[0], -2.0, 1e-9);
  const std::vector<double> t = {0.0, 0.1, 0.25, 0.3};
  double t_mean = 0.0, y_mean = 0.0;
  for (double v : t) {
    t_mean += v / 4.0;
    y_mean += -v * v / 4.0;
  }
  double stt = 0.0, sty = 0.0;
  for (double v : t) {
    stt += (v - t_mean) * (v - t_mean);
    sty += (v - t_mean) * (-v * v - y_mean);
  }
  EXPECT_NEAR(x.y().v[0], -sty / stt, 1e-9);
  // The value is still the interpolation of the two bracketing samples.
  EXPECT_NEAR(x.y().a, series.At(kStartNs + 550'000'000, 0.4).y(), 1e-15);
}

// Why the line: an offset estimated by Gauss-Newton from noisy 100 Hz samples of a smooth
// signal. With the bracketing segment's slope as the Jacobian the noise in both correlates
// and the estimate is biased by milliseconds; with the line's it is within its noise.
TEST(TimeShiftedSeries, TheLineSlopeKeepsANoisyOffsetEstimateUnbiased) {
  const auto signal = [](double t) { return std::sin(1.3 * t) + 0.5 * std::sin(3.1 * t + 1.0); };
  const double true_offset_s = 0.0123;
  double sum_error_s = 0.0;
  const int runs = 20;
  for (int run = 0; run < runs; ++run) {
    std::mt19937 rng(100 + run);
    std::normal_distribution<double> noise(0.0, 0.05);
    std::vector<int64_t> t_ns;
    std::vector<Eigen::Matrix<double, 1, 1>> values;
    for (double t = 0.0; t < 60.0; t += 0.01) {  // stamped on the sensor's clock
      t_ns.push_back(kStartNs + static_cast<int64_t>(std::llround(t * 1e9)));
      values.emplace_back(signal(t + true_offset_s) + noise(rng));
    }
    const TimeShiftedSeries<1> series(t_ns, values, "noisy");
    double offset_s = 0.0;
    for (int iteration = 0; iteration < 10; ++iteration) {
      double jtj = 0.0, jtr = 0.0;
      for (double t = 1.0; t < 59.0; t += 0.1) {  // keyframes on the IMU clock
        const int64_t t_imu = kStartNs + static_cast<int64_t>(std::llround(t * 1e9));
        const Jet x = series.At(t_imu, Jet(offset_s, 0))(0);
        const double r = x.a - signal(t);
        jtj += x.v[0] * x.v[0];
        jtr += x.v[0] * r;
      }
      offset_s -= jtr / jtj;
    }
    sum_error_s += offset_s - true_offset_s;  // t_imu = t_sensor + offset
  }
  // 20 runs of 580 rows at 0.05 noise: the mean's standard error is about 0.2 ms.
  EXPECT_LT(std::abs(sum_error_s / runs), 0.6e-3);
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
