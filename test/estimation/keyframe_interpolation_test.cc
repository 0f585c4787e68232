// The time mean over a span of samples joined by straight lines (Eq. K13b): exact for a line,
// weights that sum to one, the instant's value for an empty span, and no mean where the
// samples do not cover the span.
#include "estimation/keyframe_interpolation.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <vector>

namespace autocal {
namespace estimation {
namespace internal {
namespace {

struct Sample {
  int64_t t_ns = 0;
  double value = 0.0;
};

// Samples every period_ns from t0_ns of value(t in seconds).
template <typename F>
std::vector<Sample> Sampled(int64_t t0_ns, int64_t period_ns, int count, F value) {
  std::vector<Sample> samples;
  for (int i = 0; i < count; ++i) {
    const int64_t t = t0_ns + i * period_ns;
    samples.push_back({t, value(1e-9 * static_cast<double>(t))});
  }
  return samples;
}

const auto kValue = [](const Sample& s) { return s.value; };
constexpr int64_t kMs = 1000000;

TEST(MeanOverSpan, IsTheValueAtTheCentreForALine) {
  const auto samples = Sampled(0, 10 * kMs, 100, [](double t) { return 3.0 - 2.0 * t; });
  // A span from between two samples to between two others, centred on 0.4537 s.
  const auto mean = MeanOverSpan(samples, 353700000, 553700000, 25 * kMs, kValue);
  ASSERT_TRUE(mean.has_value());
  EXPECT_NEAR(mean->value, 3.0 - 2.0 * 0.4537, 1e-12);
}

TEST(MeanOverSpan, AveragesACurvedSignalOverTheSpanNotAtTheCentre) {
  // sin(w t) averaged over [c - h, c + h] is sin(w c) sin(w h) / (w h): the smoothing the
  // gyro's mean applies, which the wheels' mean must match.
  const double w = 2.0 * M_PI * 0.5;
  const auto samples = Sampled(0, kMs, 2000, [w](double t) { return std::sin(w * t); });
  const double c = 0.8, h = 0.1;
  const auto mean = MeanOverSpan(samples, static_cast<int64_t>((c - h) * 1e9),
                                 static_cast<int64_t>((c + h) * 1e9), 2 * kMs, kValue);
  ASSERT_TRUE(mean.has_value());
  EXPECT_NEAR(mean->value, std::sin(w * c) * std::sin(w * h) / (w * h),
              2e-6);  // trapezoids at 1 ms
  EXPECT_GT(std::abs(mean->value - std::sin(w * c)), 1e-3);
}

TEST(MeanOverSpan, WeightsSumToOneAndTheirSquaresGiveTheNoise) {
  // Constant 1: the value is the weights' sum. Twenty 10 ms segments over 0.2 s, the span's
  // ends on samples: weights 1/40 at the ends and 1/20 inside, squares 19/400 + 2/1600.
  const auto samples = Sampled(0, 10 * kMs, 100, [](double) { return 1.0; });
  const auto on_samples = MeanOverSpan(samples, 300 * kMs, 500 * kMs, 25 * kMs, kValue);
  ASSERT_TRUE(on_samples.has_value());
  EXPECT_NEAR(on_samples->value, 1.0, 1e-12);
  EXPECT_NEAR(on_samples->weight_squares, 19.0 / 400.0 + 2.0 / 1600.0, 1e-12);
  const auto between = MeanOverSpan(samples, 304 * kMs, 504 * kMs, 25 * kMs, kValue);
  ASSERT_TRUE(between.has_value());
  EXPECT_NEAR(between->value, 1.0, 1e-12);
  EXPECT_GT(between->weight_squares, 0.04);
  EXPECT_LT(between->weight_squares, 0.06);
}

TEST(MeanOverSpan, AnEmptySpanIsTheInstantsInterpolation) {
  const auto samples = Sampled(0, 10 * kMs, 10, [](double t) { return t * t; });
  const auto between = MeanOverSpan(samples, 25 * kMs, 25 * kMs, 25 * kMs, kValue);
  ASSERT_TRUE(between.has_value());
  EXPECT_NEAR(between->value, 0.5 * (0.02 * 0.02 + 0.03 * 0.03), 1e-15);
  EXPECT_NEAR(between->weight_squares, 0.5, 1e-15);
  const auto on_sample = MeanOverSpan(samples, 30 * kMs, 30 * kMs, 25 * kMs, kValue);
  ASSERT_TRUE(on_sample.has_value());
  EXPECT_EQ(on_sample->value, samples[3].value);
  EXPECT_EQ(on_sample->weight_squares, 1.0);
}

TEST(MeanOverSpan, NeedsSamplesOverTheWholeSpan) {
  auto samples = Sampled(0, 10 * kMs, 10, [](double) { return 1.0; });
  EXPECT_FALSE(MeanOverSpan(samples, -kMs, 50 * kMs, 25 * kMs, kValue).has_value());
  EXPECT_FALSE(MeanOverSpan(samples, 50 * kMs, 91 * kMs, 25 * kMs, kValue).has_value());
  EXPECT_TRUE(MeanOverSpan(samples, 0, 90 * kMs, 25 * kMs, kValue).has_value());
  EXPECT_FALSE(MeanOverSpan(samples, 60 * kMs, 40 * kMs, 25 * kMs, kValue).has_value());
  samples.erase(samples.begin() + 5, samples.begin() + 8);  // a 40 ms gap from 40 to 80 ms
  EXPECT_FALSE(MeanOverSpan(samples, 10 * kMs, 50 * kMs, 25 * kMs, kValue).has_value());
  EXPECT_TRUE(MeanOverSpan(samples, 10 * kMs, 40 * kMs, 25 * kMs, kValue).has_value());
}

}  // namespace
}  // namespace internal
}  // namespace estimation
}  // namespace autocal
