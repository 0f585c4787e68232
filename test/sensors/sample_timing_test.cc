#include "autocal/sensors/sample_timing.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <random>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/time.h"

namespace autocal {
namespace sensors {
namespace {

constexpr int64_t kStartNs = 1'700'000'000'000'000'000;

// A stream at rate_hz for duration_s: each interval jittered uniformly by +-jitter of the
// period, each sample lost with drop_probability.
std::vector<int64_t> Regular(double rate_hz, double duration_s, double jitter = 0.0,
                             double drop_probability = 0.0, uint64_t seed = 1) {
  std::mt19937_64 random(seed);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::uniform_real_distribution<double> draw(0.0, 1.0);
  const double period_s = 1.0 / rate_hz;
  std::vector<int64_t> stamps;
  for (int64_t i = 0; static_cast<double>(i) * period_s <= duration_s; ++i) {
    const double t_s = static_cast<double>(i) * period_s + jitter * period_s * 0.5 * unit(random);
    if (i > 0 && draw(random) < drop_probability) continue;
    stamps.push_back(kStartNs + SecondsToNs(t_s));
  }
  return stamps;
}

// rate_hz on average, arriving as bursts of burst_size samples 0.3 ms apart.
std::vector<int64_t> Bursty(double rate_hz, int burst_size, double duration_s) {
  const double burst_period_s = burst_size / rate_hz;
  std::vector<int64_t> stamps;
  for (int64_t b = 0; static_cast<double>(b) * burst_period_s <= duration_s; ++b) {
    for (int i = 0; i < burst_size; ++i) {
      stamps.push_back(kStartNs + SecondsToNs(static_cast<double>(b) * burst_period_s + i * 3e-4));
    }
  }
  return stamps;
}

// The longest interval between the two samples around any time on a grid of step_s.
double LongestBracketS(const std::vector<int64_t>& stamps, double step_s) {
  double longest_s = 0.0;
  for (int64_t t = stamps.front(); t < stamps.back(); t += SecondsToNs(step_s)) {
    const auto after = std::upper_bound(stamps.begin(), stamps.end(), t);
    longest_s = std::max(longest_s, NsToSeconds(*after - *(after - 1)));
  }
  return longest_s;
}

// At the simulator's rates the derived limits are the constants they replace.
TEST(SampleTiming, ReproducesTheFormerConstantsAtSimulatorRates) {
  const SampleTiming imu = MeasureTiming(Regular(200.0, 30.0), "imu");
  const SampleTiming wheel = MeasureTiming(Regular(100.0, 30.0), "wheel");
  const SampleTiming gnss = MeasureTiming(Regular(10.0, 30.0), "gnss");
  EXPECT_DOUBLE_EQ(MaxBracketingGapS(imu), 0.0125);
  EXPECT_DOUBLE_EQ(MaxBracketingGapS(wheel), 0.025);
  EXPECT_DOUBLE_EQ(MaxBracketingGapS(gnss), 0.25);
  EXPECT_EQ(SecondsToNs(MaxBracketingGapS(imu)), 12'500'000);
  EXPECT_EQ(SecondsToNs(MaxBracketingGapS(wheel)), 25'000'000);
  EXPECT_EQ(SecondsToNs(MaxBracketingGapS(gnss)), 250'000'000);
  EXPECT_DOUBLE_EQ(KeyframePeriodS(gnss, imu, &wheel), 0.1);
  EXPECT_DOUBLE_EQ(GnssTrackHalfWidthS(gnss), 1.0);
  EXPECT_FALSE(imu.bursty || wheel.bursty || gnss.bursty);
}

TEST(SampleTiming, ImuFrom25To1000Hz) {
  for (double rate_hz : {25.0, 30.0, 1000.0}) {
    const SampleTiming t = MeasureTiming(Regular(rate_hz, 20.0, 0.02), "imu");
    EXPECT_NEAR(t.rate_hz(), rate_hz, 1e-3 * rate_hz) << rate_hz << " Hz";
    EXPECT_NEAR(MaxBracketingGapS(t), 2.5 / rate_hz, 1e-3 / rate_hz) << rate_hz << " Hz";
    EXPECT_FALSE(t.bursty) << rate_hz << " Hz";
    EXPECT_EQ(t.outages, 0) << rate_hz << " Hz";
  }
}

// CAN wheel speeds arrive in bursts: the median interval is 0.3 ms, yet the rate is the mean
// one and every keyframe on a 10 ms grid is bracketed within the derived gap. Bursts of 6 and
// more samples read as 3333 Hz with every gap between them an outage before.
TEST(SampleTiming, BurstyWheelsFrom5To200Hz) {
  for (const auto& [rate_hz, burst] : {std::pair<double, int>{5.0, 3},
                                       {10.0, 2},
                                       {83.0, 4},
                                       {100.0, 6},
                                       {50.0, 10},
                                       {83.0, 12},
                                       {200.0, 20}}) {
    const std::vector<int64_t> stamps = Bursty(rate_hz, burst, 60.0);
    const SampleTiming t = MeasureTiming(stamps, "wheel");
    EXPECT_TRUE(t.bursty) << rate_hz << " Hz";
    EXPECT_NEAR(t.median_interval_s, 3e-4, 1e-9) << rate_hz << " Hz";
    EXPECT_NEAR(t.rate_hz(), rate_hz, 0.01 * rate_hz) << rate_hz << " Hz";
    EXPECT_EQ(t.outages, 0) << rate_hz << " Hz";
    EXPECT_GE(MaxBracketingGapS(t), LongestBracketS(stamps, 0.01)) << rate_hz << " Hz";
  }
}

// Bursts of 10 at 50 Hz with 3 s of the log lost: that gap alone is an outage, and the rate
// leaves it out.
TEST(SampleTiming, BurstyWheelsWithAnOutage) {
  std::vector<int64_t> stamps;
  for (int64_t t : Bursty(50.0, 10, 60.0)) {
    const double s = NsToSeconds(t - kStartNs);
    if (s < 20.0 || s >= 23.0) stamps.push_back(t);
  }
  const SampleTiming t = MeasureTiming(stamps, "wheel");
  EXPECT_EQ(t.outages, 1);
  EXPECT_NEAR(t.rate_hz(), 50.0, 0.5);
  EXPECT_NEAR(t.max_gap_s, 3.2 - 9 * 3e-4, 1e-6);
  EXPECT_LT(MaxBracketingGapS(t), 0.3);
}

// 200 Hz with 5 % jitter and 1 % of the samples lost: one lost sample is bridged, three in a
// row are not.
TEST(SampleTiming, JitteredWheelsWithDroppedSamples) {
  const SampleTiming t = MeasureTiming(Regular(200.0, 60.0, 0.05, 0.01, 3), "wheel");
  EXPECT_NEAR(t.rate_hz(), 198.0, 1.0);
  EXPECT_FALSE(t.bursty);
  EXPECT_GT(MaxBracketingGapS(t), 2.0 * 0.005 * 1.05);
  EXPECT_LT(MaxBracketingGapS(t), 4.0 * 0.005 * 0.95);
}

// GNSS with a 4 s outage: the rate ignores it, and the gap does not bridge it.
TEST(SampleTiming, GnssFrom1To20HzWithAnOutage) {
  for (double rate_hz : {1.0, 2.5, 20.0}) {
    std::vector<int64_t> stamps = Regular(rate_hz, 120.0, 0.01);
    const int64_t outage_begin = kStartNs + SecondsToNs(50.0);
    const int64_t outage_end = outage_begin + SecondsToNs(4.0);
    stamps.erase(std::remove_if(stamps.begin(), stamps.end(),
                                [&](int64_t t) { return t > outage_begin && t < outage_end; }),
                 stamps.end());
    const SampleTiming t = MeasureTiming(stamps, "gnss");
    EXPECT_NEAR(t.rate_hz(), rate_hz, 0.01 * rate_hz) << rate_hz << " Hz";
    EXPECT_EQ(t.outages, 1) << rate_hz << " Hz";
    EXPECT_GT(t.max_gap_s, 4.0) << rate_hz << " Hz";
    EXPECT_LT(MaxBracketingGapS(t), 4.0) << rate_hz << " Hz";
    EXPECT_NEAR(MaxBracketingGapS(t), 2.5 / rate_hz, 0.03 / rate_hz) << rate_hz << " Hz";
    EXPECT_DOUBLE_EQ(GnssTrackHalfWidthS(t), std::max(1.0, t.mean_interval_s * 2.5));
  }
}

// The skid-steer robot's log: IMU 30 Hz, odometry 10 Hz (median 99 ms, p99 110 ms, one
// 208 ms interval), GNSS 2.5 Hz.
TEST(SampleTiming, SkidSteerRobotLog) {
  std::vector<int64_t> odometry = {kStartNs};
  for (int i = 0; i < 3950; ++i) {
    const int k = (i * 37) % 100;  // 60 % at 99 ms, 38 % at 101 ms, 2 % at 110 ms
    const int64_t interval_ms = i == 2000 ? 208 : k < 60 ? 99 : k < 98 ? 101 : 110;
    odometry.push_back(odometry.back() + interval_ms * 1'000'000);
  }
  const SampleTiming wheel = MeasureTiming(odometry, "wheel");
  EXPECT_DOUBLE_EQ(wheel.median_interval_s, 0.099);
  EXPECT_DOUBLE_EQ(wheel.p99_interval_s, 0.110);
  EXPECT_DOUBLE_EQ(wheel.max_gap_s, 0.208);
  EXPECT_EQ(wheel.outages, 0);
  EXPECT_NEAR(MaxBracketingGapS(wheel), 0.25, 0.001);
  EXPECT_GT(MaxBracketingGapS(wheel), wheel.max_gap_s);  // every keyframe bracketed
  const SampleTiming imu = MeasureTiming(Regular(30.0, 395.0, 0.05), "imu");
  const SampleTiming gnss = MeasureTiming(Regular(2.5, 395.0, 0.02), "gnss");
  EXPECT_NEAR(MaxBracketingGapS(imu), 2.5 / 30.0, 1e-4);
  EXPECT_NEAR(MaxBracketingGapS(gnss), 1.0, 0.002);
  EXPECT_NEAR(KeyframePeriodS(gnss, imu, &wheel), 0.4, 1e-3);
  EXPECT_NEAR(GnssTrackHalfWidthS(gnss), 1.0, 1e-3);
  // Without the receiver the odometry's 10 Hz sets it: one sample between keyframes.
  EXPECT_NEAR(KeyframePeriodS(imu, &wheel), 0.1, 0.002);
  EXPECT_NEAR(KeyframePeriodS(imu, nullptr), 0.1, 0.002);  // three IMU samples
}

TEST(SampleTiming, KeyframePeriodIsClamped) {
  const SampleTiming fast = MeasureTiming(Regular(100.0, 10.0), "gnss");
  const SampleTiming slow = MeasureTiming(Regular(1.0, 100.0), "gnss");
  const SampleTiming imu = MeasureTiming(Regular(400.0, 10.0), "imu");
  EXPECT_DOUBLE_EQ(KeyframePeriodS(fast, imu, nullptr), 0.05);
  EXPECT_DOUBLE_EQ(KeyframePeriodS(slow, imu, nullptr), 0.5);
  EXPECT_DOUBLE_EQ(GnssTrackHalfWidthS(slow), 2.5);
  // Wheels slower than the fixes set the period: one wheel sample between keyframes.
  const SampleTiming gnss = MeasureTiming(Regular(10.0, 30.0), "gnss");
  const SampleTiming wheel = MeasureTiming(Bursty(5.0, 3, 30.0), "wheel");
  EXPECT_NEAR(KeyframePeriodS(gnss, imu, &wheel), 0.2, 0.005);  // 153 samples over 30 s
  // A 25 Hz IMU: three samples between keyframes.
  const SampleTiming slow_imu = MeasureTiming(Regular(25.0, 30.0), "imu");
  EXPECT_NEAR(KeyframePeriodS(gnss, slow_imu, nullptr), 0.12, 1e-6);
}

TEST(SampleTiming, RefusesTooFewOrUnorderedStamps) {
  EXPECT_THAT([] { MeasureTiming({kStartNs}, "gnss.csv"); },
              ::testing::ThrowsMessage<Error>(
                  ::testing::HasSubstr("gnss.csv: 1 stamp(s); the timing needs at least two")));
  EXPECT_THAT(
      [] {
        MeasureTiming({kStartNs, kStartNs + 5, kStartNs + 5}, "wheel.csv");
      },
      ::testing::ThrowsMessage<Error>(::testing::HasSubstr(
          "wheel.csv: stamps must increase: stamp 2 at 1700000000000000005 ns follows "
          "1700000000000000005 ns")));
}

}  // namespace
}  // namespace sensors
}  // namespace autocal
