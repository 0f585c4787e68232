// Sensor rates, stamp models and clock offsets: every measurement, however it is stamped, is
// the exact truth at the instant the model says (noise off), and the sign of each clock
// offset is the project's t_imu = t_sensor + offset.

#include <gtest/gtest.h>

#include <GeographicLib/LocalCartesian.hpp>
#include <algorithm>
#include <cmath>
#include <functional>
#include <string>

#include "autocal/common/error.h"
#include "autocal/common/time.h"
#include "autocal/sim/simulator.h"
#include "sim/sim_test_util.h"

namespace autocal {
namespace sim {
namespace {

// An urban log without LiDAR and without noise, moving after the 1.5 s standstill.
SimulationOptions ExactLog(double duration_s) {
  SimulationOptions options = test::SmallLog(ScenarioType::kUrban, duration_s).WithoutNoise();
  options.lidar.enabled = false;
  return options;
}

// The wheel rates a sample measured at trajectory time t_s holds.
Eigen::Vector2d TrueWheelRates(const Simulator& simulator, double t_s) {
  const BodyState state = simulator.scenario().trajectory->StateAt(t_s);
  const double v = (state.T_W_B.q.conjugate() * state.v_W).x();
  const double w = state.omega_B.z();
  const sensors::Calibration& c = simulator.true_calibration();
  return Eigen::Vector2d((v - 0.5 * c.track_width_m * w) / c.wheel_radius_left_m,
                         (v + 0.5 * c.track_width_m * w) / c.wheel_radius_right_m);
}

double WheelError(const Simulator& simulator, const sensors::WheelSample& s, double t_s) {
  return (Eigen::Vector2d(s.left_rad_s, s.right_rad_s) - TrueWheelRates(simulator, t_s))
      .cwiseAbs()
      .maxCoeff();
}

TEST(ClockTest, ImuRatesFrom25To1000HzWithJitteredStampsAreTheTruthAtEachStamp) {
  for (double rate : {25.0, 1000.0}) {
    for (double jitter_periods : {0.0, 0.3}) {
      SimulationOptions options = ExactLog(3.0);
      options.imu.noise.update_rate_hz = rate;
      options.imu.stamp_jitter_s = jitter_periods / rate;
      const Simulator simulator(options);
      const ImuLog imu = simulator.GenerateImu();
      ASSERT_EQ(imu.samples.size(), static_cast<size_t>(std::floor(3.0 * rate)) + 1);
      const int64_t period_ns = SecondsToNs(1.0 / rate);
      int64_t max_deviation_ns = 0;
      const sensors::Calibration& c = simulator.true_calibration();
      const geometry::Pose3d T_V_I = geometry::Pose3d(c.q_I_V, c.p_I_V).Inverse();
      for (size_t k = 0; k < imu.samples.size(); ++k) {
        const int64_t t_ns = imu.samples[k].t_ns;
        if (k > 0) {
          ASSERT_GT(t_ns, imu.samples[k - 1].t_ns) << "stamps increase";
        }
        const int64_t grid_ns = options.start_time_ns + static_cast<int64_t>(k) * period_ns;
        max_deviation_ns = std::max(max_deviation_ns, std::abs(t_ns - grid_ns));
        // Exact body rate at the stamp (the truth written for that stamp is the same state).
        const BodyState state =
            simulator.scenario().trajectory->StateAt(simulator.TimeOf(t_ns), T_V_I);
        ASSERT_LT((imu.samples[k].gyro_rad_s - state.omega_B).norm(), 1e-12) << "sample " << k;
        ASSERT_EQ(imu.truth[k].t_ns, t_ns);
      }
      if (jitter_periods == 0.0) {
        EXPECT_EQ(max_deviation_ns, 0) << rate << " Hz: a plain grid";
      } else {
        EXPECT_LE(max_deviation_ns, SecondsToNs(options.imu.stamp_jitter_s) + 1);
        EXPECT_GT(max_deviation_ns, SecondsToNs(0.5 * options.imu.stamp_jitter_s))
            << rate << " Hz: the jitter is drawn over its range";
      }
    }
  }
}

TEST(ClockTest, WheelSampleStampedTIsTheTruthAtImuTimeTPlusOffset) {
  for (double offset : {-0.38, 0.15}) {
    SimulationOptions options = ExactLog(12.0);
    options.wheel.config.rate_hz = 10.0;
    options.wheel.time_offset_wheel_imu_s = offset;
    const Simulator simulator(options);
    const WheelLog log = simulator.GenerateWheelLog();
    ASSERT_EQ(log.samples.size(), 121u);
    double right_sign = 0.0, wrong_sign = 0.0;
    for (size_t i = 0; i < log.samples.size(); ++i) {
      const int64_t t_ns = log.samples[i].t_ns;
      ASSERT_EQ(log.true_t_ns[i], t_ns + SecondsToNs(offset));
      const double t_imu = simulator.TimeOf(t_ns) + offset;
      right_sign = std::max(right_sign, WheelError(simulator, log.samples[i], t_imu));
      if (t_imu > 3.0 && t_imu < 10.0) {
        wrong_sign =
            std::max(wrong_sign, WheelError(simulator, log.samples[i], t_imu - 2.0 * offset));
      }
    }
    EXPECT_LT(right_sign, 1e-9) << "offset " << offset;
    EXPECT_GT(wrong_sign, 0.1) << "the opposite sign must not fit (offset " << offset << ")";
  }
}

TEST(ClockTest, WheelRatesFrom5To200HzAreTheTruthAtTheirStamps) {
  for (double rate : {5.0, 200.0}) {
    SimulationOptions options = ExactLog(8.0);
    options.wheel.config.rate_hz = rate;
    const Simulator simulator(options);
    const sensors::WheelSamples samples = simulator.GenerateWheel();
    EXPECT_EQ(samples.size(), static_cast<size_t>(8.0 * rate) + 1) << rate << " Hz";
    double worst = 0.0;
    for (const sensors::WheelSample& s : samples) {
      worst = std::max(worst, WheelError(simulator, s, simulator.TimeOf(s.t_ns)));
    }
    EXPECT_LT(worst, 1e-9) << rate << " Hz";
  }
}

TEST(ClockTest, WheelTruthCarriesSpeedAndYawRateAtEachMeasurement) {
  SimulationOptions options = ExactLog(12.0);
  options.wheel.config.rate_hz = 50.0;
  const Simulator simulator(options);
  const WheelLog log = simulator.GenerateWheelLog();
  const sensors::Calibration& c = simulator.true_calibration();
  ASSERT_EQ(log.speed_m_s.size(), log.samples.size());
  ASSERT_EQ(log.yaw_rate_rad_s.size(), log.samples.size());
  double max_speed = 0.0;
  for (size_t i = 0; i < log.samples.size(); ++i) {
    const double v_l = log.samples[i].left_rad_s * c.wheel_radius_left_m;
    const double v_r = log.samples[i].right_rad_s * c.wheel_radius_right_m;
    EXPECT_NEAR(0.5 * (v_l + v_r), log.speed_m_s[i], 1e-12);
    EXPECT_NEAR((v_r - v_l) / c.track_width_m, log.yaw_rate_rad_s[i], 1e-12);
    max_speed = std::max(max_speed, log.speed_m_s[i]);
  }
  EXPECT_GT(max_speed, 5.0);
}

TEST(ClockTest, GnssFixStampedTIsTheAntennaAtImuTimeTPlusOffset) {
  SimulationOptions options = ExactLog(12.0);
  options.gnss.config.rate_hz = 20.0;
  options.gnss.num_outages = 0;
  options.gnss.time_offset_gnss_imu_s = -0.2;
  const Simulator simulator(options);
  const GnssLog gnss = simulator.GenerateGnss();
  ASSERT_EQ(gnss.fixes.size(), 241u);
  const GeographicLib::LocalCartesian enu(options.gnss.origin_lat_deg, options.gnss.origin_lon_deg,
                                          options.gnss.origin_alt_m);
  const Eigen::Vector3d p_I_A = simulator.true_calibration().p_I_A;
  double right_sign = 0.0, wrong_sign = 0.0;
  for (size_t i = 0; i < gnss.fixes.size(); ++i) {
    const sensors::GnssFix& fix = gnss.fixes[i];
    Eigen::Vector3d measured;
    enu.Forward(fix.lat_deg, fix.lon_deg, fix.alt_m, measured.x(), measured.y(), measured.z());
    const double t_imu = simulator.TimeOf(fix.t_ns) + options.gnss.time_offset_gnss_imu_s;
    right_sign = std::max(right_sign, (measured - simulator.ImuPoseAt(t_imu) * p_I_A).norm());
    EXPECT_LT((gnss.true_p_W_A[i] - simulator.ImuPoseAt(t_imu) * p_I_A).norm(), 1e-9);
    if (t_imu > 3.0) {
      wrong_sign = std::max(
          wrong_sign, (measured - simulator.ImuPoseAt(simulator.TimeOf(fix.t_ns)) * p_I_A).norm());
    }
  }
  EXPECT_LT(right_sign, 1e-6);
  EXPECT_GT(wrong_sign, 1.0) << "0.2 s at >= 10 m/s";
}

TEST(ClockTest, WheelBurstsAreStampedAtArrivalAndHoldTheTruthOfTheirMeasurement) {
  SimulationOptions options = ExactLog(6.0);
  options.wheel.config.rate_hz = 83.0;
  options.wheel.burst_size = 4;
  options.wheel.burst_span_s = 0.002;
  const Simulator simulator(options);
  const WheelLog log = simulator.GenerateWheelLog();
  const double period = NsToSeconds(SecondsToNs(1.0 / 83.0));
  ASSERT_EQ(log.samples.size(), static_cast<size_t>(std::floor(6.0 / period)) + 1);
  double worst = 0.0, max_delay = 0.0;
  int gaps = 0, close = 0;
  for (size_t i = 0; i < log.samples.size(); ++i) {
    const int64_t t_ns = log.samples[i].t_ns;
    const double delay = NsToSeconds(t_ns - log.true_t_ns[i]);
    EXPECT_GE(delay, 0.0) << "a sample arrives after it is measured";
    max_delay = std::max(max_delay, delay);
    worst =
        std::max(worst, WheelError(simulator, log.samples[i], simulator.TimeOf(log.true_t_ns[i])));
    if (i == 0) continue;
    const double step = NsToSeconds(t_ns - log.samples[i - 1].t_ns);
    ASSERT_GT(step, 0.0) << "stamps increase";
    if (std::abs(step - 0.0005) < 1e-9) ++close;                // within a burst: span / 4
    if (std::abs(step - (4 * period - 0.0015)) < 1e-6) ++gaps;  // between bursts
  }
  EXPECT_LT(worst, 1e-9);
  EXPECT_NEAR(max_delay, 3.0 * period, 1e-6) << "the first of a group waits for the last";
  // 498 samples in groups of 4 (the last group, of 2, is cut at the end of the log).
  EXPECT_GE(close, 3 * 123);
  EXPECT_GE(gaps, 122);
}

TEST(ClockTest, JitteredAndDroppedWheelSamplesAreASubsetOfTheFullLog) {
  SimulationOptions options = ExactLog(20.0);
  options.wheel.config.rate_hz = 10.0;
  options.wheel.add_noise = true;  // the noise of a sample does not depend on the drops
  const WheelLog full = Simulator(options).GenerateWheelLog();
  options.wheel.drop_probability = 0.2;
  options.wheel.stamp_jitter_s = 0.03;
  const Simulator simulator(options);
  const WheelLog dropped = simulator.GenerateWheelLog();
  ASSERT_EQ(full.samples.size(), 201u);
  // Binomial(201, 0.8): mean 160.8, sigma 5.7.
  EXPECT_GT(dropped.samples.size(), 140u);
  EXPECT_LT(dropped.samples.size(), 182u);
  size_t j = 0;
  int64_t max_jitter_ns = 0;
  for (size_t i = 0; i < dropped.samples.size(); ++i) {
    // The sample's grid index: the nearest 100 ms point.
    const int64_t grid_ns =
        SecondsToNs(0.1) *
        ((dropped.true_t_ns[i] - options.start_time_ns + SecondsToNs(0.05)) / SecondsToNs(0.1));
    while (j < full.samples.size() && full.true_t_ns[j] - options.start_time_ns < grid_ns) ++j;
    ASSERT_LT(j, full.samples.size());
    max_jitter_ns =
        std::max(max_jitter_ns, std::abs(dropped.true_t_ns[i] - options.start_time_ns - grid_ns));
    // Same noise draw as in the full log; the motion differs by the jitter only.
    const double noise_full = full.samples[j].left_rad_s -
                              TrueWheelRates(simulator, simulator.TimeOf(full.true_t_ns[j])).x();
    const double noise_dropped =
        dropped.samples[i].left_rad_s -
        TrueWheelRates(simulator, simulator.TimeOf(dropped.true_t_ns[i])).x();
    EXPECT_NEAR(noise_full, noise_dropped, 1e-9) << "sample " << i;
    EXPECT_EQ(dropped.samples[i].t_ns, dropped.true_t_ns[i]) << "no offset, no bursts";
  }
  EXPECT_LE(max_jitter_ns, SecondsToNs(0.03) + 1);
  EXPECT_GT(max_jitter_ns, SecondsToNs(0.015));
}

TEST(ClockTest, GnssRatesFrom1To20Hz) {
  for (double rate : {1.0, 2.5, 20.0}) {
    SimulationOptions options = ExactLog(10.0);
    options.gnss.config.rate_hz = rate;
    options.gnss.num_outages = 0;
    const GnssLog gnss = Simulator(options).GenerateGnss();
    EXPECT_EQ(gnss.fixes.size(), static_cast<size_t>(std::floor(10.0 * rate + 1e-9)) + 1) << rate;
  }
}

TEST(ClockTest, RefusesStampOptionsOutOfRange) {
  auto expect_error = [](const std::function<void(SimulationOptions*)>& change,
                         const std::string& field) {
    SimulationOptions options = ExactLog(2.0);
    change(&options);
    try {
      Simulator simulator(options);
      ADD_FAILURE() << "accepted bad " << field;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
    }
  };
  expect_error([](SimulationOptions* o) { o->imu.noise.update_rate_hz = 10.0; }, "update_rate_hz");
  expect_error([](SimulationOptions* o) { o->imu.stamp_jitter_s = 0.002; }, "imu stamp_jitter_s");
  expect_error([](SimulationOptions* o) { o->wheel.stamp_jitter_s = -0.001; },
               "wheel stamp_jitter_s");
  expect_error([](SimulationOptions* o) { o->wheel.burst_size = 0; }, "burst_size");
  expect_error([](SimulationOptions* o) { o->wheel.burst_span_s = 0.01; }, "burst_span_s");
  expect_error([](SimulationOptions* o) { o->wheel.drop_probability = 0.9; }, "drop_probability");
  expect_error([](SimulationOptions* o) { o->wheel.time_offset_wheel_imu_s = 2.5; },
               "time_offset_wheel_imu_s");
  expect_error([](SimulationOptions* o) { o->gnss.time_offset_gnss_imu_s = -3.0; },
               "time_offset_gnss_imu_s");
  expect_error([](SimulationOptions* o) { o->true_calibration.time_offset_wheel_imu_s = 0.1; },
               "true_calibration.time_offset_wheel_imu_s");
  expect_error([](SimulationOptions* o) { o->true_calibration.time_offset_gnss_imu_s = 0.1; },
               "true_calibration.time_offset_gnss_imu_s");
}

// The truth (groundtruth/calibration.yaml, the information bound at the truth) carries the
// simulated clocks; the nominal guess does not know them.
TEST(ClockTest, TheTruthCarriesTheSimulatedClocksAndTheNominalDoesNot) {
  SimulationOptions options = ExactLog(2.0);
  options.wheel.time_offset_wheel_imu_s = -0.38;
  options.gnss.time_offset_gnss_imu_s = 0.2;
  const Simulator simulator(options);
  EXPECT_EQ(simulator.true_calibration().time_offset_wheel_imu_s, -0.38);
  EXPECT_EQ(simulator.true_calibration().time_offset_gnss_imu_s, 0.2);
  EXPECT_EQ(simulator.nominal_calibration().time_offset_wheel_imu_s, 0.0);
  EXPECT_EQ(simulator.nominal_calibration().time_offset_gnss_imu_s, 0.0);
}

}  // namespace
}  // namespace sim
}  // namespace autocal
