#include "autocal/estimation/sliding_window.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <iostream>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/time.h"
#include "autocal/common/units.h"
#include "autocal/estimation/imu_motion_table.h"
#include "autocal/factors/loss.h"
#include "autocal/geometry/manifolds.h"
#include "autocal/geometry/so3.h"
#include "autocal/sim/simulator.h"
#include "estimation/sliding_window_factors.h"
#include "estimation/sliding_window_internal.h"
#include "estimation/true_keyframe.h"
#include "factors/factor_test_utils.h"
#include "support/simulation_cache.h"

namespace autocal {
namespace estimation {
namespace {

constexpr double kGravity = 9.80665;
constexpr int64_t kStart = 1'700'000'000'000'000'000;
constexpr int64_t kImuStep = 5'000'000;  // 200 Hz

// A car at rest: the IMU reads gravity only.
sensors::ImuSample StillImu(int64_t t_ns) {
  sensors::ImuSample s;
  s.t_ns = t_ns;
  s.accel_m_s2 = Eigen::Vector3d(0.0, 0.0, kGravity);
  return s;
}

// A small sweep of 0.1 s: a few points on a wall, each with its time.
lidar::LidarSweep SmallSweep(int64_t t_ns) {
  lidar::LidarSweep sweep;
  sweep.t_ns = t_ns;
  const int n = 20;
  sweep.cloud.points.resize(3, n);
  sweep.cloud.time_s.resize(n);
  for (int i = 0; i < n; ++i) {
    sweep.cloud.points.col(i) = Eigen::Vector3d(10.0, -5.0 + 0.5 * i, 0.2 * (i % 5));
    sweep.cloud.time_s(i) = 0.1 * i / n;
  }
  return sweep;
}

SlidingWindowState StillState() {
  SlidingWindowState s;
  s.t_ns = kStart;
  return s;
}

SlidingWindowOptions FastOptions() {
  SlidingWindowOptions options;
  options.solver.max_iterations = 3;
  return options;
}

TEST(SlidingWindowStreaming, DropsOutOfOrderAndLateSamples) {
  SlidingWindowEstimator estimator(FastOptions(), sensors::Calibration(), StillState());
  EXPECT_TRUE(estimator.AddImu(StillImu(kStart - kImuStep)));
  EXPECT_TRUE(estimator.AddImu(StillImu(kStart)));
  EXPECT_FALSE(estimator.AddImu(StillImu(kStart)));             // not newer
  EXPECT_FALSE(estimator.AddImu(StillImu(kStart - kImuStep)));  // older
  EXPECT_EQ(estimator.counters().out_of_order, 2);

  sensors::WheelSample wheel;
  wheel.t_ns = kStart - 1;  // before the initial keyframe: its interval is closed
  EXPECT_FALSE(estimator.AddWheel(wheel));
  EXPECT_EQ(estimator.counters().late, 1);
  wheel.t_ns = kStart + 10'000'000;
  EXPECT_TRUE(estimator.AddWheel(wheel));
  EXPECT_FALSE(estimator.AddWheel(wheel));
  EXPECT_EQ(estimator.counters().out_of_order, 3);

  GnssPosition fix;
  fix.t_ns = kStart + 50'000'000;
  fix.sigma_enu_m = Eigen::Vector3d(0.03, 0.03, 0.06);
  EXPECT_TRUE(estimator.AddGnss(fix));
  fix.t_ns -= 1;
  EXPECT_FALSE(estimator.AddGnss(fix));
  EXPECT_EQ(estimator.counters().out_of_order, 4);
  EXPECT_EQ(estimator.counters().late_gnss, 0);

  EXPECT_TRUE(estimator.AddSweep(SmallSweep(kStart + 100'000'000)));
  EXPECT_FALSE(estimator.AddSweep(SmallSweep(kStart + 50'000'000)));
  EXPECT_EQ(estimator.counters().out_of_order, 5);
  EXPECT_EQ(estimator.counters().wheel_accepted, 1);
  EXPECT_EQ(estimator.counters().gnss_accepted, 1);
  EXPECT_EQ(estimator.counters().sweeps_accepted, 1);
}

// A fix stamped at or before the newest keyframe comes after its interval was solved: dropped
// as late, and counted apart (the pipeline warns with the count).
TEST(SlidingWindowStreaming, CountsTheGnssFixesDroppedAsLate) {
  SlidingWindowEstimator estimator(FastOptions(), sensors::Calibration(), StillState());
  GnssPosition fix;
  fix.sigma_enu_m = Eigen::Vector3d(0.03, 0.03, 0.06);
  fix.t_ns = kStart;  // the initial keyframe's own time
  EXPECT_FALSE(estimator.AddGnss(fix));
  sensors::WheelSample wheel;
  wheel.t_ns = kStart - 1;
  EXPECT_FALSE(estimator.AddWheel(wheel));
  EXPECT_EQ(estimator.counters().late, 2);
  EXPECT_EQ(estimator.counters().late_gnss, 1);
}

// A sweep whose keyframe would land just after the newest keyframe (here the initial state,
// as when the window starts at a state the initializer placed with another time offset) is
// dropped as late; before, the IMU factor over that one sample threw on its singular
// covariance.
TEST(SlidingWindowStreaming, DropsASweepTooCloseToTheNewestKeyframe) {
  const SlidingWindowOptions options = FastOptions();
  SlidingWindowEstimator estimator(options, sensors::Calibration(), StillState());
  // A sweep's keyframe sits at its points' middle (KeyframeTime), this long after its stamp.
  const lidar::LidarSweep probe = SmallSweep(kStart);
  const int64_t middle_ns = KeyframeTime(probe, 0.0) - probe.t_ns;
  int64_t t = kStart;
  estimator.AddImu(StillImu(t));
  // Keyframe 0.5 ms after the initial state, then one a sweep period later.
  const lidar::LidarSweep close = SmallSweep(kStart - middle_ns + 500'000);
  const lidar::LidarSweep next = SmallSweep(close.t_ns + 100'000'000);
  while (t < next.t_ns + 200'000'000) estimator.AddImu(StillImu(t += kImuStep));
  EXPECT_FALSE(estimator.AddSweep(close));
  EXPECT_EQ(estimator.counters().late, 1);
  EXPECT_EQ(estimator.window_size(), 1);
  EXPECT_TRUE(estimator.AddSweep(next));
  EXPECT_EQ(estimator.window_size(), 2);
  EXPECT_EQ(estimator.latest_state().t_ns, next.t_ns + middle_ns);
}

// The partners a window walks once the extrinsic settled are the first of its list: the
// farthest keyframes pairing reaches, window_size away (docs/sliding_window.md, "Partner walk").
TEST(SlidingWindowPairing, ListsTheFarthestKeyframesPairingReachesFirst) {
  EXPECT_EQ(WindowPartnerOffsets(10), (std::vector<int>{-10, 10, -5, 5, -8, 8, -3, 3, -2, 2}));
  EXPECT_EQ(WindowPartnerOffsets(20), (std::vector<int>{-20, 20, -5, 5, -8, 8, -3, 3, -2, 2}));
  EXPECT_EQ(WindowPartnerOffsets(4), (std::vector<int>{-4, 4, -3, 3, -2, 2}));
  EXPECT_EQ(WindowPartnerOffsets(2), (std::vector<int>{-2, 2}));
  EXPECT_EQ(WindowPartnerOffsets(1), (std::vector<int>{-1, 1}));
  const SlidingWindowOptions defaults;
  EXPECT_EQ(defaults.pairing.partner_offsets, WindowPartnerOffsets(defaults.window_size));
  // A shorter window keeps the offsets it can hold, up to its size (while it pairs, the new
  // keyframe is in and the oldest not yet out), the farthest of them first.
  SlidingWindowOptions shorter = defaults;
  shorter.window_size = 4;
  EXPECT_EQ(internal::PairingWithinWindow(shorter).partner_offsets,
            (std::vector<int>{-3, 3, -2, 2}));
  shorter.window_size = 5;
  EXPECT_EQ(internal::PairingWithinWindow(shorter).partner_offsets,
            (std::vector<int>{-5, 5, -3, 3, -2, 2}));
}

TEST(SlidingWindowStreaming, RejectsInvalidData) {
  SlidingWindowEstimator estimator(FastOptions(), sensors::Calibration(), StillState());
  EXPECT_THROW(estimator.AddImu(StillImu(kStart + kImuStep)), Error);  // starts after the state
  sensors::ImuSample bad = StillImu(kStart);
  bad.gyro_rad_s.x() = std::nan("");
  EXPECT_THROW(estimator.AddImu(bad), Error);
  GnssPosition fix;
  fix.t_ns = kStart + 1;
  fix.sigma_enu_m = Eigen::Vector3d(0.03, 0.0, 0.06);
  EXPECT_THROW(estimator.AddGnss(fix), Error);
  lidar::LidarSweep no_time = SmallSweep(kStart + 100'000'000);
  no_time.cloud.time_s.resize(0);
  EXPECT_THROW(estimator.AddSweep(no_time), Error);
  // Options that the constructor refuses, each changed from the defaults.
  const auto expect_rejected = [](const char* what,
                                  const std::function<void(SlidingWindowOptions*)>& change) {
    SCOPED_TRACE(what);
    SlidingWindowOptions options;
    change(&options);
    EXPECT_THROW(SlidingWindowEstimator(options, sensors::Calibration(), StillState()), Error);
  };
  expect_rejected("window_size 1", [](SlidingWindowOptions* o) { o->window_size = 1; });
  expect_rejected("a sweep paired with itself", [](SlidingWindowOptions* o) {
    o->pairing.partner_offsets = {-5, 0};
  });
  expect_rejected("no partners", [](SlidingWindowOptions* o) { o->pairing.partner_offsets = {}; });
  expect_rejected("no partner within the window", [](SlidingWindowOptions* o) {
    o->window_size = 4;
    o->pairing.partner_offsets = {-5, 5};
  });
  expect_rejected("a partner offset twice", [](SlidingWindowOptions* o) {
    o->pairing.partner_offsets = {-5, 5, -5};
  });
  expect_rejected("fallback partners, which only the batch walks", [](SlidingWindowOptions* o) {
    o->pairing.fallback_partner_offsets = {1, -1};
  });
  expect_rejected("a zero trust region",
                  [](SlidingWindowOptions* o) { o->solver.initial_trust_region_radius = 0.0; });
  expect_rejected("a NaN gradient tolerance",
                  [](SlidingWindowOptions* o) { o->solver.gradient_tolerance = std::nan(""); });
  expect_rejected("a negative parameter tolerance",
                  [](SlidingWindowOptions* o) { o->solver.parameter_tolerance = -1.0; });
  expect_rejected("max_plane_misses < 0",
                  [](SlidingWindowOptions* o) { o->window_pairing.max_plane_misses = -1; });
  expect_rejected("max_plane_misses > 255",
                  [](SlidingWindowOptions* o) { o->window_pairing.max_plane_misses = 256; });
  expect_rejected("residual_max_range_m < 0",
                  [](SlidingWindowOptions* o) { o->pairing.residual_max_range_m = -1.0; });
  expect_rejected("residual_max_range_m NaN", [](SlidingWindowOptions* o) {
    o->pairing.residual_max_range_m = std::numeric_limits<double>::quiet_NaN();
  });
  expect_rejected("a tested fixed block the window estimates", [](SlidingWindowOptions* o) {
    o->tested_fixed_blocks = {sensors::CalibrationBlockId::kTrackWidth};
  });
  expect_rejected("a tested fixed block the window has no setting for",
                  [](SlidingWindowOptions* o) {
                    o->tested_fixed_blocks = {sensors::CalibrationBlockId::kWheelTimeOffset};
                  });
  expect_rejected("settled_partner_count 0",
                  [](SlidingWindowOptions* o) { o->window_pairing.settled_partner_count = 0; });
  expect_rejected("a zero effective-track prior",
                  [](SlidingWindowOptions* o) { o->calibration_prior.effective_track_m = 0.0; });
  expect_rejected("a NaN odometry speed-scale prior", [](SlidingWindowOptions* o) {
    o->calibration_prior.odometry_speed_scale = std::nan("");
  });
  expect_rejected("a negative wheel speed-scale prior",
                  [](SlidingWindowOptions* o) { o->calibration_prior.wheel_speed_scale = -0.03; });
  expect_rejected("a NaN keyframe interval",
                  [](SlidingWindowOptions* o) { o->min_keyframe_interval_s = std::nan(""); });
  expect_rejected("a NaN IMU coverage margin",
                  [](SlidingWindowOptions* o) { o->imu_coverage_margin_s = std::nan(""); });
  expect_rejected("settled_extrinsic_deg < 0",
                  [](SlidingWindowOptions* o) { o->window_pairing.settled_extrinsic_deg = -0.1; });
  expect_rejected("max_point_to_plane_m 0",
                  [](SlidingWindowOptions* o) { o->pairing.max_point_to_plane_m = 0.0; });
  expect_rejected("wheel_gyro_mean_span_s < 0",
                  [](SlidingWindowOptions* o) { o->wheel_rows.gyro_mean_span_s = -0.01; });
  expect_rejected("wheel_rows.max_turning_axis_error_deg < 0",
                  [](SlidingWindowOptions* o) { o->wheel_rows.max_turning_axis_error_deg = -1.0; });
  expect_rejected("a negative planar-rotation sigma", [](SlidingWindowOptions* o) {
    o->wheel_rows.planar_rotation_sigma_rad_s = -0.01;
  });
  expect_rejected("min_keyframe_interval_s < 0",
                  [](SlidingWindowOptions* o) { o->min_keyframe_interval_s = -0.01; });
  expect_rejected("an initial state covariance that is not positive definite",
                  [](SlidingWindowOptions* o) {
                    o->initial_state_covariance = Eigen::Matrix<double, 15, 15>::Identity();
                    (*o->initial_state_covariance)(4, 4) = -1.0;
                  });
  expect_rejected("an initial state covariance that is not symmetric", [](SlidingWindowOptions* o) {
    o->initial_state_covariance = Eigen::Matrix<double, 15, 15>::Identity();
    (*o->initial_state_covariance)(0, 1) = 0.5;
  });
  expect_rejected("gate_extrinsic_factor < 0",
                  [](SlidingWindowOptions* o) { o->window_pairing.gate_extrinsic_factor = -0.25; });
  expect_rejected("gate_extrinsic_free_deg NaN", [](SlidingWindowOptions* o) {
    o->window_pairing.gate_extrinsic_free_deg = std::nan("");
  });
  expect_rejected("calibration_prior.mean with a NaN", [](SlidingWindowOptions* o) {
    o->calibration_prior.mean = sensors::Calibration();
    o->calibration_prior.mean->p_I_L.y() = std::nan("");
  });
  expect_rejected("per-axis sigmas of a scalar block", [](SlidingWindowOptions* o) {
    o->calibration_prior.axis_sigmas[sensors::CalibrationBlockId::kTimeOffset] =
        Eigen::Vector3d::Constant(0.01);
  });
  expect_rejected("a per-axis sigma of zero", [](SlidingWindowOptions* o) {
    o->calibration_prior.axis_sigmas[sensors::CalibrationBlockId::kGnssLeverArm] =
        Eigen::Vector3d(0.01, 0.0, 0.3);
  });
  expect_rejected("calibration_prior.mean with a zero quaternion", [](SlidingWindowOptions* o) {
    o->calibration_prior.mean = sensors::Calibration();
    o->calibration_prior.mean->q_I_V.coeffs().setZero();
  });
  SlidingWindowOptions options;
  options.window_pairing.gate_extrinsic_factor = 0.0;  // a fixed gate
  EXPECT_NO_THROW(SlidingWindowEstimator(options, sensors::Calibration(), StillState()));
}

// The calibration priors sit at calibration_prior.mean when it is set, else at the initial
// calibration. At rest the lever arm and the time offset are not observed, so the priors alone
// place them.
TEST(SlidingWindowStreaming, CentresTheCalibrationPriorsAtTheirMean) {
  const sensors::Calibration initial;
  sensors::Calibration mean = initial;
  mean.p_I_L += Eigen::Vector3d(0.05, -0.02, 0.01);
  mean.time_offset_lidar_imu_s += 0.003;
  for (const bool with_mean : {false, true}) {
    SCOPED_TRACE(with_mean ? "with a mean" : "without");
    SlidingWindowOptions options = FastOptions();
    if (with_mean) options.calibration_prior.mean = mean;
    SlidingWindowEstimator estimator(options, initial, StillState());
    int64_t t = kStart - kImuStep;
    estimator.AddImu(StillImu(t));
    for (int k = 1; k <= 4; ++k) {
      const int64_t t_sweep = kStart + k * 100'000'000;
      estimator.AddSweep(SmallSweep(t_sweep));
      while (t < t_sweep + 200'000'000) estimator.AddImu(StillImu(t += kImuStep));
    }
    ASSERT_EQ(estimator.counters().updates, 4);
    const sensors::Calibration& expected = with_mean ? mean : initial;
    EXPECT_LT((estimator.calibration().p_I_L - expected.p_I_L).norm(), 1e-4);
    EXPECT_NEAR(estimator.calibration().time_offset_lidar_imu_s, expected.time_offset_lidar_imu_s,
                1e-5);
  }
}

TEST(SlidingWindowStreaming, BuffersSweepUntilImuCoversIt) {
  const SlidingWindowOptions options = FastOptions();
  SlidingWindowEstimator estimator(options, sensors::Calibration(), StillState());
  int64_t t = kStart;
  estimator.AddImu(StillImu(t));
  const lidar::LidarSweep sweep = SmallSweep(kStart + 100'000'000);
  // Covered once the IMU reaches the last point plus the coverage margin (offset 0).
  const int64_t needed =
      sweep.t_ns + SecondsToNs(sweep.cloud.time_s.maxCoeff() + options.imu_coverage_margin_s);
  while (t + kImuStep < needed) estimator.AddImu(StillImu(t += kImuStep));
  EXPECT_TRUE(estimator.AddSweep(sweep));
  EXPECT_EQ(estimator.pending_sweeps(), 1);
  EXPECT_EQ(estimator.window_size(), 1);
  estimator.AddImu(StillImu(t += kImuStep));
  EXPECT_EQ(estimator.pending_sweeps(), 0);
  EXPECT_EQ(estimator.window_size(), 2);
  // The keyframe sits at the middle of the sweep's points; at rest it stays put.
  const double middle_s = 0.5 * (sweep.cloud.time_s.minCoeff() + sweep.cloud.time_s.maxCoeff());
  EXPECT_GT(middle_s, 0.0);
  EXPECT_EQ(estimator.latest_state().t_ns, sweep.t_ns + SecondsToNs(middle_s));
  EXPECT_LT(estimator.latest_state().p_W_I.norm(), 1e-6);
  EXPECT_LT(estimator.latest_state().v_W_I.norm(), 1e-6);
}

// Keyframes from AddKeyframeAt (a window without the LiDAR): each made once the IMU covers
// its time plus the margin, with the sweep keyframes' streaming rules, the LiDAR blocks held
// at their initial value (their prior, centred elsewhere, would pull them) and left out of
// the covariance.
TEST(SlidingWindowTimedKeyframes, MakesKeyframesWithoutSweepsAndHoldsTheLidarBlocks) {
  SlidingWindowOptions options = FastOptions();
  options.window_size = 4;
  sensors::Calibration initial;
  initial.p_I_L = Eigen::Vector3d(0.5, 0.1, 1.2);
  initial.time_offset_lidar_imu_s = 0.01;
  options.calibration_prior.mean = initial;
  options.calibration_prior.mean->p_I_L += Eigen::Vector3d(0.05, -0.02, 0.01);
  options.calibration_prior.mean->time_offset_lidar_imu_s += 0.003;
  SlidingWindowEstimator estimator(options, initial, StillState());
  int64_t t = kStart - kImuStep;
  estimator.AddImu(StillImu(t));
  const int num_keyframes = 12;
  for (int k = 1; k <= num_keyframes; ++k) {
    const int64_t t_keyframe = kStart + k * 100'000'000;
    EXPECT_TRUE(estimator.AddKeyframeAt(t_keyframe));
    EXPECT_EQ(estimator.pending_sweeps(), 1);
    const int64_t needed = t_keyframe + SecondsToNs(options.imu_coverage_margin_s);
    while (t + kImuStep < needed) estimator.AddImu(StillImu(t += kImuStep));
    EXPECT_EQ(estimator.counters().updates, k - 1);
    estimator.AddImu(StillImu(t += kImuStep));
    ASSERT_EQ(estimator.counters().updates, k);
    EXPECT_EQ(estimator.latest_state().t_ns, t_keyframe);
  }
  EXPECT_EQ(estimator.window_size(), options.window_size);
  EXPECT_EQ(estimator.counters().marginalizations, num_keyframes + 1 - options.window_size);
  EXPECT_EQ(estimator.counters().keyframe_times_accepted, num_keyframes);
  EXPECT_EQ(estimator.last_associated_points(), 0);
  EXPECT_LT(estimator.latest_state().p_W_I.norm(), 1e-3);
  EXPECT_EQ(estimator.calibration().p_I_L, initial.p_I_L);
  EXPECT_EQ(estimator.calibration().time_offset_lidar_imu_s, initial.time_offset_lidar_imu_s);
  const CalibrationCovariance covariance = estimator.ComputeCalibrationCovariance();
  EXPECT_THAT(covariance.names, ::testing::Not(::testing::Contains(std::string("q_I_L"))));
  EXPECT_THAT(covariance.names, ::testing::Not(::testing::Contains(std::string("p_I_L"))));
  EXPECT_THAT(covariance.names, ::testing::Contains(std::string("p_I_A")));

  // Streaming rules: not after the last time asked for, too close to the newest keyframe.
  const int64_t last = kStart + num_keyframes * 100'000'000;
  EXPECT_FALSE(estimator.AddKeyframeAt(last));
  EXPECT_EQ(estimator.counters().out_of_order, 1);
  EXPECT_FALSE(estimator.AddKeyframeAt(last + 1000));
  EXPECT_EQ(estimator.counters().late, 1);
  // Two times waiting for the IMU together: the second one too close to the first is late
  // too, though it follows the newest keyframe by more than the interval.
  const int64_t min_interval = SecondsToNs(options.min_keyframe_interval_s);
  EXPECT_TRUE(estimator.AddKeyframeAt(last + 2 * min_interval));
  EXPECT_FALSE(estimator.AddKeyframeAt(last + 2 * min_interval + min_interval / 2));
  EXPECT_EQ(estimator.counters().late, 2);
  EXPECT_TRUE(estimator.AddKeyframeAt(last + 3 * min_interval));
  EXPECT_EQ(estimator.pending_sweeps(), 2);
  while (estimator.pending_sweeps() > 0) estimator.AddImu(StillImu(t += kImuStep));
  EXPECT_EQ(estimator.latest_state().t_ns, last + 3 * min_interval);
  // Keyframes come from one source.
  EXPECT_THROW(estimator.AddSweep(SmallSweep(last + 100'000'000)), Error);
  SlidingWindowEstimator with_sweeps(FastOptions(), sensors::Calibration(), StillState());
  with_sweeps.AddSweep(SmallSweep(kStart + 100'000'000));
  EXPECT_THROW(with_sweeps.AddKeyframeAt(kStart + 200'000'000), Error);
}

// A keyframe with no IMU sample since the newest one has no IMU factor (one interpolated step
// has a singular covariance): it is skipped and counted, and the next keyframe's factor spans
// the dropout. Keyframes every 0.1 s over a still car whose IMU drops `dropout_ns` from
// `dropout_at_ns` (0: no dropout), sampled every `imu_step_ns`; returns the counters.
SlidingWindowCounters StreamAcrossAnImuDropout(int64_t imu_step_ns, int64_t keyframe_step_ns,
                                               int64_t dropout_at_ns, int64_t dropout_ns) {
  SlidingWindowOptions options = FastOptions();
  options.window_size = 4;
  options.imu.noise.update_rate_hz = 1e9 / static_cast<double>(imu_step_ns);
  SlidingWindowEstimator estimator(options, sensors::Calibration(), StillState());
  int64_t t = kStart;
  estimator.AddImu(StillImu(t));
  const auto add_imu_until = [&](int64_t until_ns) {
    while (t + imu_step_ns <= until_ns) {
      t += imu_step_ns;
      const bool dropped = t >= dropout_at_ns && t < dropout_at_ns + dropout_ns;
      if (!dropped) estimator.AddImu(StillImu(t));
    }
  };
  for (int k = 1; k <= 10; ++k) {
    EXPECT_TRUE(estimator.AddKeyframeAt(kStart + k * keyframe_step_ns));
    add_imu_until(kStart + k * keyframe_step_ns + 100'000'000);
  }
  add_imu_until(t + 500'000'000);
  EXPECT_NO_THROW(estimator.ComputeCalibrationCovariance());
  EXPECT_LT(estimator.latest_state().p_W_I.norm(), 1e-3);
  return estimator.counters();
}

TEST(SlidingWindowTimedKeyframes, SkipsKeyframesInAnImuDropout) {
  // 200 Hz, 150 ms missing from 0.35 s: the keyframe at 0.4 s has no sample since 0.3 s.
  const SlidingWindowCounters dropout =
      StreamAcrossAnImuDropout(kImuStep, 100'000'000, kStart + 350'000'000, 150'000'000);
  EXPECT_EQ(dropout.without_imu, 1);
  EXPECT_EQ(dropout.updates, 9);
  // 0.5 s missing: the five keyframes inside it are skipped, the one at 0.9 s spans it.
  const SlidingWindowCounters long_dropout =
      StreamAcrossAnImuDropout(kImuStep, 100'000'000, kStart + 305'000'000, 500'000'000);
  EXPECT_EQ(long_dropout.without_imu, 5);
  EXPECT_EQ(long_dropout.updates, 5);
  // A 30 Hz IMU (33.3 ms) under keyframes 25 ms apart, more than min_keyframe_interval_s: every
  // fourth interval holds no sample.
  const SlidingWindowCounters slow_imu = StreamAcrossAnImuDropout(33'333'333, 25'000'000, 0, 0);
  EXPECT_GT(slow_imu.without_imu, 0);
  EXPECT_EQ(slow_imu.updates + slow_imu.without_imu, 10);
  const SlidingWindowCounters none = StreamAcrossAnImuDropout(kImuStep, 100'000'000, 0, 0);
  EXPECT_EQ(none.without_imu, 0);
  EXPECT_EQ(none.updates, 10);
}

// An update that throws (here its solve: an IMU reading of 1e300 m/s^2 overflows the rows)
// leaves the window between two states, the keyframe taken in and not solved; every later call
// refuses to go on with that error instead of building on it.
TEST(SlidingWindowTimedKeyframes, AFailedUpdateStopsTheEstimator) {
  SlidingWindowEstimator estimator(FastOptions(), sensors::Calibration(), StillState());
  int64_t t = kStart - kImuStep;
  estimator.AddImu(StillImu(t));
  ASSERT_TRUE(estimator.AddKeyframeAt(kStart + 100'000'000));
  sensors::ImuSample wild = StillImu(t += kImuStep);
  wild.accel_m_s2.x() = 1e300;
  estimator.AddImu(wild);
  std::string failure;
  for (int k = 0; k < 100 && failure.empty(); ++k) {
    try {
      estimator.AddImu(StillImu(t += kImuStep));
    } catch (const Error& e) {
      failure = e.what();
    }
  }
  ASSERT_FALSE(failure.empty()) << "the update did not fail";
  EXPECT_THAT(failure, ::testing::HasSubstr("window solver"));
  for (const std::function<void()>& call :
       std::vector<std::function<void()>>{[&] { estimator.AddImu(StillImu(t += kImuStep)); },
                                          [&] { estimator.AddKeyframeAt(kStart + 300'000'000); },
                                          [&] { estimator.ComputeCalibrationCovariance(); }}) {
    try {
      call();
      ADD_FAILURE() << "a call went on after the failed update";
    } catch (const Error& e) {
      EXPECT_THAT(e.what(), ::testing::HasSubstr("an earlier update failed"));
      EXPECT_THAT(e.what(), ::testing::HasSubstr(failure));
    }
  }
}

// A platform at rest whose fixes, one per keyframe, scatter four times their stated std
// horizontally and as stated vertically, streamed into a window of 4 over 100 keyframes.
struct StillFixesStream {
  GnssStdScale scale_at_first_fix;  // gnss_std_scale() before the first fix is attached
  GnssNoiseFromResiduals noise;
  GnssStdScale scale_at_end;
  GnssStdScale largest_scale;
  SlidingWindowCounters counters;
};
StillFixesStream StreamStillFixes(SlidingWindowOptions options, int num_keyframes) {
  options.window_size = 4;
  const sensors::Calibration calibration;
  SlidingWindowEstimator estimator(options, calibration, StillState());
  StillFixesStream out;
  out.scale_at_first_fix = estimator.gnss_std_scale();
  std::mt19937_64 random(9);
  std::normal_distribution<double> normal(0.0, 1.0);
  int64_t t = kStart - kImuStep;
  estimator.AddImu(StillImu(t));
  for (int k = 1; k <= num_keyframes; ++k) {
    const int64_t t_keyframe = kStart + int64_t{100'000'000} * k;
    GnssPosition fix;
    fix.t_ns = t_keyframe - 50'000'000;
    fix.sigma_enu_m = Eigen::Vector3d(0.1, 0.1, 0.2);
    fix.p_W_A = calibration.p_I_A +
                Eigen::Vector3d(0.4 * normal(random), 0.4 * normal(random), 0.2 * normal(random));
    EXPECT_TRUE(estimator.AddGnss(fix));
    EXPECT_TRUE(estimator.AddKeyframeAt(t_keyframe));
    const int64_t needed = t_keyframe + SecondsToNs(options.imu_coverage_margin_s);
    while (t < needed) estimator.AddImu(StillImu(t += kImuStep));
  }
  EXPECT_EQ(estimator.counters().updates, num_keyframes);
  out.noise = estimator.gnss_noise();
  out.scale_at_end = estimator.gnss_std_scale();
  out.largest_scale = estimator.largest_gnss_std_scale();
  out.counters = estimator.counters();
  return out;
}

// Eq. N2 in the window, on StreamStillFixes. Once 67 horizontal rows are marginalized the later
// fixes' horizontal std is scaled by what the rows show; the vertical one stays. Without the
// option nothing is measured. Measured: 4.81 over 194 rows, vertical 0.91, 63 fixes scaled.
// The rows read above their true 4: the Cauchy loss at 3 stated sigmas down-weights most of
// these fixes, and the trajectory they hold loosely wanders 1.4 m (0.25 m with the std stated
// right), so the residuals are not the fitted ones of a least-squares solve.
TEST(SlidingWindowTimedKeyframes, ScalesLaterFixesByTheMarginalizedRowsScatter) {
  const int num_keyframes = 100;
  for (const bool from_residuals : {true, false}) {
    SCOPED_TRACE(from_residuals ? "from the residuals" : "as stated");
    SlidingWindowOptions options = FastOptions();
    options.gnss_noise_from_residuals = from_residuals;
    const StillFixesStream stream = StreamStillFixes(options, num_keyframes);
    const GnssNoiseFromResiduals& noise = stream.noise;
    if (from_residuals) {
      std::cout << "horizontal " << noise.horizontal.robust_sigma << " over "
                << noise.horizontal.rows << " rows, vertical " << noise.vertical.robust_sigma
                << " over " << noise.vertical.rows << ", " << stream.counters.gnss_scaled
                << " fixes scaled\n";
      EXPECT_EQ(noise.horizontal.rows, 2 * noise.vertical.rows);
      EXPECT_GE(noise.vertical.rows, static_cast<size_t>(num_keyframes - 4));
      EXPECT_GT(noise.horizontal.scale, 3.0);
      EXPECT_EQ(noise.horizontal.scale, noise.horizontal.robust_sigma);
      EXPECT_EQ(noise.vertical.scale, 1.0);
      EXPECT_TRUE(stream.scale_at_end == noise.Scale());
      EXPECT_GE(stream.largest_scale.horizontal, stream.scale_at_end.horizontal);
      EXPECT_EQ(stream.largest_scale.vertical, 1.0);
      EXPECT_GT(stream.counters.gnss_scaled, num_keyframes / 2);
      EXPECT_LT(stream.counters.gnss_scaled, num_keyframes);
    } else {
      EXPECT_EQ(noise.horizontal.rows, 0u);
      EXPECT_TRUE(noise.Scale().IsOne());
      EXPECT_TRUE(stream.scale_at_end.IsOne());
      EXPECT_TRUE(stream.largest_scale.IsOne());
      EXPECT_EQ(stream.counters.gnss_scaled, 0);
    }
  }
}

// A scale given with the options (a start's fit, GnssInertialKeyframes::gnss_std_scale) scales
// every fix from the first, per axis group until the window's own rows judge that group: then
// the horizontal rows' scatter, and the vertical rows', which scatter as stated, back to one.
// Without the window's own rows, the given scale throughout.
TEST(SlidingWindowTimedKeyframes, GivenGnssStdScaleHoldsUntilTheRowsJudge) {
  const int num_keyframes = 100;
  const GnssStdScale given{4.0, 1.5};
  for (const bool from_residuals : {true, false}) {
    SCOPED_TRACE(from_residuals ? "from the residuals" : "given only");
    SlidingWindowOptions options = FastOptions();
    options.gnss_noise_from_residuals = from_residuals;
    options.gnss_std_scale = given;
    const StillFixesStream stream = StreamStillFixes(options, num_keyframes);
    EXPECT_TRUE(stream.scale_at_first_fix == given);
    EXPECT_EQ(stream.counters.gnss_scaled, num_keyframes);
    if (from_residuals) {
      EXPECT_GE(stream.noise.vertical.rows, kMinGnssNoiseRows);
      EXPECT_GT(stream.scale_at_end.horizontal, 3.0);
      EXPECT_EQ(stream.scale_at_end.horizontal, stream.noise.horizontal.scale);
      EXPECT_EQ(stream.scale_at_end.vertical, 1.0);
      // The vertical fixes took the given 1.5 before the rows judged them: the largest says so.
      EXPECT_EQ(stream.largest_scale.vertical, given.vertical);
    } else {
      EXPECT_TRUE(stream.scale_at_end == given);
      EXPECT_TRUE(stream.largest_scale == given);
    }
  }
  SlidingWindowOptions invalid = FastOptions();
  invalid.gnss_std_scale.vertical = 0.0;
  EXPECT_THROW(SlidingWindowEstimator(invalid, sensors::Calibration(), StillState()), Error);
}

// A block's prior may state one sigma per axis (a lever arm measured in x and y, not in z): a
// block nothing else informs keeps exactly those sigmas, where the block's one sigma would give
// every axis the same.
TEST(SlidingWindowTimedKeyframes, KeepsAPriorSigmaPerAxis) {
  const Eigen::Vector3d sigma_m(0.01, 0.02, 0.3);
  for (const bool per_axis : {false, true}) {
    SCOPED_TRACE(per_axis ? "per axis" : "one sigma");
    SlidingWindowOptions options = FastOptions();
    options.window_size = 4;
    options.calibration_prior.gnss_lever_arm_m = sigma_m.maxCoeff();
    if (per_axis)
      options.calibration_prior.axis_sigmas[sensors::CalibrationBlockId::kGnssLeverArm] = sigma_m;
    SlidingWindowEstimator estimator(options, sensors::Calibration(), StillState());
    int64_t t = kStart - kImuStep;
    estimator.AddImu(StillImu(t));
    for (int k = 1; k <= 6; ++k) {
      const int64_t t_keyframe = kStart + k * 100'000'000;
      ASSERT_TRUE(estimator.AddKeyframeAt(t_keyframe));
      while (t < t_keyframe + SecondsToNs(options.imu_coverage_margin_s)) {
        estimator.AddImu(StillImu(t += kImuStep));
      }
    }
    ASSERT_EQ(estimator.counters().updates, 6);
    const CalibrationCovariance covariance = estimator.ComputeCalibrationCovariance();
    const auto name = std::find(covariance.names.begin(), covariance.names.end(), "p_I_A");
    ASSERT_NE(name, covariance.names.end());
    const int first = covariance.offsets[static_cast<size_t>(name - covariance.names.begin())];
    for (int i = 0; i < 3; ++i) {
      const double expected = per_axis ? sigma_m(i) : sigma_m.maxCoeff();
      EXPECT_NEAR(std::sqrt(covariance.covariance(first + i, first + i)), expected, 1e-9 * expected)
          << "axis " << i;
    }
  }
}

// The window never holds more than N keyframes; the prior exists from the first
// marginalization on and the trajectory keeps every keyframe.
TEST(SlidingWindowMarginalization, KeepsAtMostNKeyframesAndAPrior) {
  SlidingWindowOptions options = FastOptions();
  options.window_size = 4;
  SlidingWindowEstimator estimator(options, sensors::Calibration(), StillState());
  int64_t t = kStart - kImuStep;
  estimator.AddImu(StillImu(t));
  const int num_sweeps = 12;
  int max_window = 0;
  for (int k = 1; k <= num_sweeps; ++k) {
    const int64_t t_sweep = kStart + k * 100'000'000;
    estimator.AddSweep(SmallSweep(t_sweep));
    while (t < t_sweep + 200'000'000) estimator.AddImu(StillImu(t += kImuStep));
    max_window = std::max(max_window, estimator.window_size());
    const bool marginalized = estimator.counters().updates + 1 > options.window_size;
    EXPECT_EQ(estimator.has_marginalization_prior(), marginalized) << "after sweep " << k;
  }
  EXPECT_EQ(estimator.counters().updates, num_sweeps);
  EXPECT_EQ(max_window, options.window_size);
  EXPECT_EQ(estimator.counters().marginalizations, num_sweeps + 1 - options.window_size);
  const std::vector<SlidingWindowState> trajectory = estimator.Trajectory();
  ASSERT_EQ(static_cast<int>(trajectory.size()), num_sweeps + 1);
  for (size_t k = 1; k < trajectory.size(); ++k) {
    EXPECT_GT(trajectory[k].t_ns, trajectory[k - 1].t_ns);
  }
  // At rest with a tight initial prior, the marginalized prior holds the window still.
  EXPECT_LT(estimator.latest_state().p_W_I.norm(), 1e-3);
  EXPECT_LT(
      geometry::AngularDistance(estimator.latest_state().q_W_I, Eigen::Quaterniond::Identity()) *
          kRadToDeg,
      0.01);
}

// ---------------------------------------------------------------------------------------------
// The window's wheel rows (docs/sliding_window.md, "Wheel rows") are the wheel factor's rows
// (Eq. F22) at the state ImuPreintegration::Predict gives, whitened at the current radii and
// track width.

// 0.1 s of a turning, accelerating drive preintegrated from the biases b_g_lin, b_a_lin, its
// samples drawn after std::srand(seed).
sensors::ImuPreintegration TurningPreintegration(const Eigen::Vector3d& b_g_lin,
                                                 const Eigen::Vector3d& b_a_lin, unsigned seed) {
  std::srand(seed);
  sensors::ImuPreintegration pim(sensors::ImuNoise{}, sensors::PreintegrationOptions{}, b_g_lin,
                                 b_a_lin);
  for (int i = 0; i < 20; ++i) {
    pim.IntegrateStep(Eigen::Vector3d(0.05, -0.02, 0.3) + 0.1 * Eigen::Vector3d::Random(),
                      Eigen::Vector3d(0.8, 0.1, kGravity) + 0.3 * Eigen::Vector3d::Random(), 0.005);
  }
  return pim;
}

TEST(SlidingWindowPropagatedWheelResidual, IsTheWheelResidualAtThePredictedState) {
  const Eigen::Vector3d b_g_lin(0.002, -0.001, 0.003), b_a_lin(0.05, -0.02, 0.01);
  const sensors::ImuPreintegration pim = TurningPreintegration(b_g_lin, b_a_lin, 9);
  factors::WheelMeasurement m;
  m.left_rad_s = 24.0;
  m.right_rad_s = 25.5;
  m.gyro_rad_s = Eigen::Vector3d(0.01, 0.02, 0.31);
  const factors::WheelFactorOptions wheel_options;
  // speed_variance: the propagated velocity's along x_V (Eq. W7), here (2 cm/s)^2.
  const double encoder_sigma = 0.05, gyro_sigma = 0.003, speed_variance = 4e-4;
  const std::unique_ptr<ceres::CostFunction> propagated(internal::PropagatedWheelResidual::Create(
      pim, m, wheel_options, encoder_sigma, gyro_sigma, speed_variance));
  const factors::WheelResidual wheel(m, wheel_options);
  for (int trial = 0; trial < 10; ++trial) {
    Eigen::Quaterniond q(Eigen::Quaterniond::UnitRandom());
    Eigen::Vector3d p = 10.0 * Eigen::Vector3d::Random(), v = 8.0 * Eigen::Vector3d::Random();
    Eigen::Vector3d b_g = b_g_lin + 0.002 * Eigen::Vector3d::Random();
    Eigen::Vector3d b_a = b_a_lin + 0.05 * Eigen::Vector3d::Random();
    Eigen::Quaterniond q_I_V(Eigen::AngleAxisd(0.02 * trial, Eigen::Vector3d::UnitX()) *
                             Eigen::AngleAxisd(M_PI / 2.0, Eigen::Vector3d::UnitZ()));
    Eigen::Vector3d p_I_V(-1.2, 0.1, -0.4);
    double r_l = 0.33, r_r = 0.335, track = 1.6 + 0.01 * trial;
    const double* blocks[] = {
        q.coeffs().data(), v.data(), b_g.data(), b_a.data(), q_I_V.coeffs().data(),
        p_I_V.data(),      &r_l,     &r_r,       &track};
    Eigen::Vector4d got;
    ASSERT_TRUE(propagated->Evaluate(blocks, got.data(), nullptr));

    sensors::NavState<double> x;
    x.q_W_I = q;
    x.p_W_I = p;
    x.v_W_I = v;
    const sensors::NavState<double> at = pim.Predict(x, b_g, b_a);
    Eigen::Vector4d expected;
    ASSERT_TRUE(wheel(at.q_W_I.coeffs().data(), at.v_W_I.data(), b_g.data(), q_I_V.coeffs().data(),
                      p_I_V.data(), &r_l, &r_r, &track, expected.data()));
    const double radius_sq = r_l * r_l + r_r * r_r;
    expected(0) *= wheel_options.speed_sigma_m_s /
                   std::sqrt(0.25 * encoder_sigma * encoder_sigma * radius_sq + speed_variance);
    expected(1) *= wheel_options.yaw_rate_sigma_rad_s * track /
                   std::sqrt(encoder_sigma * encoder_sigma * radius_sq +
                             track * track * gyro_sigma * gyro_sigma);
    EXPECT_LT((got - expected).norm(), 1e-9 * (1.0 + expected.norm()))
        << "trial " << trial << ": " << got.transpose() << " vs " << expected.transpose();
    // Off the measured wheel rates the rows are far from zero: the check is not vacuous.
    EXPECT_GT(expected.norm(), 1.0);
  }
}

// The other wheel forms' window rows (linear speeds, Eq. F25; the controller's twist, Eq. F26) are
// their factor's rows at the state ImuPreintegration::Predict gives, the yaw-rate row in the Deming
// form of the window's wheel rows (and the linear speeds' speed row at the current scales); zero
// where the measurement is what the predicted state gives; their autodiff Jacobians pass the
// GradientChecker on random states, with and without the non-holonomic rows.
struct FormTrial {
  Eigen::Quaterniond q = Eigen::Quaterniond::UnitRandom();
  Eigen::Vector3d p = 10.0 * Eigen::Vector3d::Random(), v = 8.0 * Eigen::Vector3d::Random();
  Eigen::Vector3d b_g, b_a;
  Eigen::Quaterniond q_I_V;
  Eigen::Vector3d p_I_V{-1.2, 0.1, -0.4};
  FormTrial(const Eigen::Vector3d& b_g_lin, const Eigen::Vector3d& b_a_lin, int trial)
      : b_g(b_g_lin + 0.002 * Eigen::Vector3d::Random()),
        b_a(b_a_lin + 0.05 * Eigen::Vector3d::Random()),
        q_I_V(Eigen::AngleAxisd(0.02 * trial, Eigen::Vector3d::UnitX()) *
              Eigen::AngleAxisd(M_PI / 2.0, Eigen::Vector3d::UnitZ())) {}
  // The rear axle's forward speed and yaw rate at the state `pim` predicts (the raw gyro
  // `gyro_rad_s`, its bias removed, for the yaw rate).
  Eigen::Vector2d VehicleMotion(const sensors::ImuPreintegration& pim,
                                const Eigen::Vector3d& gyro_rad_s) const {
    sensors::NavState<double> x;
    x.q_W_I = q;
    x.p_W_I = p;
    x.v_W_I = v;
    const sensors::NavState<double> at = pim.Predict(x, b_g, b_a);
    const factors::VehicleMotion<double> motion =
        factors::PredictVehicleMotion(at.q_W_I.coeffs().data(), at.v_W_I.data(), b_g.data(),
                                      q_I_V.coeffs().data(), p_I_V.data(), gyro_rad_s);
    return Eigen::Vector2d(motion.v_V.x(), motion.w_V.z());
  }
};

TEST(SlidingWindowPropagatedFormResiduals, VanishAtTheTruthAndPassGradientChecker) {
  const Eigen::Vector3d b_g_lin(0.002, -0.001, 0.003), b_a_lin(0.05, -0.02, 0.01);
  const sensors::ImuPreintegration pim = TurningPreintegration(b_g_lin, b_a_lin, 13);
  const geometry::RightQuaternionManifold quaternion;
  const double speed_sigma = 0.02, gyro_sigma = 0.003;
  for (int trial = 0; trial < 12; ++trial) {
    FormTrial x(b_g_lin, b_a_lin, trial);
    factors::WheelFactorOptions options;
    options.non_holonomic = trial % 2 == 0;
    const Eigen::Vector3d gyro =
        Eigen::Vector3d(0.01, 0.02, 0.31) + 0.2 * Eigen::Vector3d::Random();
    const Eigen::Vector2d motion = x.VehicleMotion(pim, gyro);
    const std::string context = "trial " + std::to_string(trial);

    // Linear speeds that the predicted motion gives through the scales and the track.
    double s_l = 1.01 + 0.002 * trial, s_r = 0.99, track = 1.6 + 0.01 * trial;
    factors::WheelSpeedMeasurement speeds;
    speeds.left_m_s = (motion(0) - 0.5 * track * motion(1)) / s_l;
    speeds.right_m_s = (motion(0) + 0.5 * track * motion(1)) / s_r;
    speeds.gyro_rad_s = gyro;
    // Odd trials add a propagated velocity variance (Eq. W7) to the speed row.
    const double speed_variance = trial % 2 == 1 ? 3e-4 : 0.0;
    const std::unique_ptr<ceres::CostFunction> speed_cost(
        internal::PropagatedWheelSpeedResidual::Create(pim, speeds, options, speed_sigma,
                                                       gyro_sigma, speed_variance));
    std::vector<double*> blocks = {
        x.q.coeffs().data(), x.v.data(), x.b_g.data(), x.b_a.data(), x.q_I_V.coeffs().data(),
        x.p_I_V.data(),      &s_l,       &s_r,         &track};
    Eigen::Vector4d r;
    ASSERT_TRUE(speed_cost->Evaluate(blocks.data(), r.data(), nullptr));
    EXPECT_LT(r.head<2>().norm(), 1e-9) << context;
    // Off the truth, the rows are the factor's, rescaled as the header says.
    s_l += 0.02;
    ASSERT_TRUE(speed_cost->Evaluate(blocks.data(), r.data(), nullptr));
    const factors::WheelSpeedResidual plain(speeds, options);
    Eigen::Vector4d expected;
    {
      sensors::NavState<double> state;
      state.q_W_I = x.q;
      state.p_W_I = x.p;
      state.v_W_I = x.v;
      const sensors::NavState<double> at = pim.Predict(state, x.b_g, x.b_a);
      ASSERT_TRUE(plain(at.q_W_I.coeffs().data(), at.v_W_I.data(), x.b_g.data(),
                        x.q_I_V.coeffs().data(), x.p_I_V.data(), &s_l, &s_r, &track,
                        expected.data()));
    }
    const double scale_sq = s_l * s_l + s_r * s_r;
    expected(0) *= options.speed_sigma_m_s /
                   std::sqrt(0.25 * speed_sigma * speed_sigma * scale_sq + speed_variance);
    expected(1) *=
        options.yaw_rate_sigma_rad_s * track /
        std::sqrt(speed_sigma * speed_sigma * scale_sq + track * track * gyro_sigma * gyro_sigma);
    const int rows = options.non_holonomic ? 4 : 2;
    EXPECT_LT((r - expected).head(rows).norm(), 1e-9 * (1.0 + expected.head(rows).norm()))
        << context;
    EXPECT_GT(expected.head<2>().norm(), 0.1) << context;
    test::ExpectGradientCheckPasses(
        *speed_cost,
        {&quaternion, nullptr, nullptr, nullptr, &quaternion, nullptr, nullptr, nullptr, nullptr},
        blocks, 1e-6, context + ", linear speeds");

    // The controller's twist that the predicted motion gives through k_v and b_eff.
    double k_v = 0.97, b_eff = 1.9 + 0.02 * trial;
    factors::OdometryMeasurement twist;
    twist.controller_track_m = 1.2;
    twist.speed_m_s = motion(0) / k_v;
    twist.yaw_rate_rad_s = motion(1) * b_eff / (k_v * twist.controller_track_m);
    twist.gyro_rad_s = gyro;
    const std::unique_ptr<ceres::CostFunction> twist_cost(
        internal::PropagatedOdometryResidual::Create(pim, twist, options, gyro_sigma));
    std::vector<double*> twist_blocks = {
        x.q.coeffs().data(),     x.v.data(),     x.b_g.data(), x.b_a.data(),
        x.q_I_V.coeffs().data(), x.p_I_V.data(), &k_v,         &b_eff};
    ASSERT_TRUE(twist_cost->Evaluate(twist_blocks.data(), r.data(), nullptr));
    EXPECT_LT(r.head<2>().norm(), 1e-9) << context;
    b_eff += 0.1;
    ASSERT_TRUE(twist_cost->Evaluate(twist_blocks.data(), r.data(), nullptr));
    EXPECT_GT(std::abs(r(1)), 0.1) << context;
    test::ExpectGradientCheckPasses(
        *twist_cost,
        {&quaternion, nullptr, nullptr, nullptr, &quaternion, nullptr, nullptr, nullptr},
        twist_blocks, 1e-6, context + ", odometry");
  }
}

// The analytic wheel rows against their autodiff form (every block on its tangent space, to
// 1e-9) and against numeric differentiation (GradientChecker), on random states, with and
// without the non-holonomic rows; a shared radius and a non-positive sigma are refused.
TEST(SlidingWindowPropagatedWheelFactor, JacobiansMatchAutodiffAndGradientChecker) {
  const Eigen::Vector3d b_g_lin(0.002, -0.001, 0.003), b_a_lin(0.05, -0.02, 0.01);
  const sensors::ImuPreintegration pim = TurningPreintegration(b_g_lin, b_a_lin, 11);
  const geometry::RightQuaternionManifold quaternion;
  const std::vector<const ceres::Manifold*> manifolds = {
      &quaternion, nullptr, nullptr, nullptr, &quaternion, nullptr, nullptr, nullptr, nullptr};
  const double encoder_sigma = 0.05, gyro_sigma = 0.003;
  // Ridders' first step 1e-4 of each value instead of 1e-2: with the speed row's variance added
  // (Eq. W7) a 1 % step of a radius moved the extrapolated derivative of both scaled rows by up to
  // 2 % on some states, while the autodiff twin agrees to 1e-9.
  ceres::NumericDiffOptions small_steps;
  small_steps.ridders_relative_initial_step_size = 1e-4;
  for (int trial = 0; trial < 12; ++trial) {
    factors::WheelMeasurement m;
    m.left_rad_s = 24.0 + 3.0 * Eigen::Vector2d::Random()(0);
    m.right_rad_s = 25.5 + 3.0 * Eigen::Vector2d::Random()(0);
    m.gyro_rad_s = Eigen::Vector3d(0.01, 0.02, 0.31) + 0.2 * Eigen::Vector3d::Random();
    factors::WheelFactorOptions wheel_options;
    wheel_options.non_holonomic = trial % 2 == 0;
    wheel_options.lateral_sigma_m_s = 0.03;
    wheel_options.vertical_sigma_m_s = 0.11;
    // Every third trial without a propagated velocity variance (Eq. W7).
    const double speed_variance = trial % 3 == 0 ? 0.0 : 2e-4 * trial;
    const internal::PropagatedWheelFactor analytic(pim, m, wheel_options, encoder_sigma, gyro_sigma,
                                                   speed_variance);
    const std::unique_ptr<ceres::CostFunction> autodiff(internal::PropagatedWheelResidual::Create(
        pim, m, wheel_options, encoder_sigma, gyro_sigma, speed_variance));
    ASSERT_EQ(analytic.num_residuals(), autodiff->num_residuals());
    ASSERT_EQ(analytic.parameter_block_sizes(), autodiff->parameter_block_sizes());
    Eigen::Quaterniond q(Eigen::Quaterniond::UnitRandom());
    Eigen::Vector3d v = 8.0 * Eigen::Vector3d::Random();
    Eigen::Vector3d b_g = b_g_lin + 0.002 * Eigen::Vector3d::Random();
    Eigen::Vector3d b_a = b_a_lin + 0.05 * Eigen::Vector3d::Random();
    Eigen::Quaterniond q_I_V(Eigen::AngleAxisd(0.02 * trial, Eigen::Vector3d::UnitX()) *
                             Eigen::AngleAxisd(M_PI / 2.0, Eigen::Vector3d::UnitZ()));
    Eigen::Vector3d p_I_V(-1.2, 0.1, -0.4);
    double r_l = 0.33 + 0.01 * trial, r_r = 0.335, track = 1.6 + 0.01 * trial;
    const std::vector<double*> blocks = {
        q.coeffs().data(), v.data(), b_g.data(), b_a.data(), q_I_V.coeffs().data(),
        p_I_V.data(),      &r_l,     &r_r,       &track};
    const std::string context = "trial " + std::to_string(trial);
    test::ExpectSameJacobians(analytic, *autodiff, manifolds, blocks, 1e-9, context);
    test::ExpectGradientCheckPasses(analytic, manifolds, blocks, 1e-6, context, small_steps);
  }
  factors::WheelFactorOptions shared;
  shared.shared_radius = true;
  EXPECT_THROW(internal::PropagatedWheelFactor(pim, factors::WheelMeasurement{}, shared,
                                               encoder_sigma, gyro_sigma, 0.0),
               Error);
  EXPECT_THROW(internal::PropagatedWheelFactor(pim, factors::WheelMeasurement{},
                                               factors::WheelFactorOptions{}, 0.0, gyro_sigma, 0.0),
               Error);
  EXPECT_THROW(internal::PropagatedWheelFactor(pim, factors::WheelMeasurement{},
                                               factors::WheelFactorOptions{}, encoder_sigma,
                                               gyro_sigma, -1e-4),
               Error);
}

// Eq. W7 against Monte Carlo: 0.4 s of a 5 m/s turn at 0.3 rad/s sampled at 100 Hz with the
// vibrating skid steer's noise (30 times the bench densities), the mount yawed 90 deg and
// rolled 10 deg; 4000 noisy realizations of the body velocity in V at the propagated state.
// Each variance within 10 % of the formula's (3.5 standard errors of the sample variance).
TEST(SlidingWindowPropagatedVelocityCovariance, MatchesMonteCarlo) {
  sensors::ImuNoise noise;
  noise.gyroscope_noise_density *= 30.0;
  noise.accelerometer_noise_density *= 30.0;
  noise.update_rate_hz = 100.0;
  const double dt = 0.01, g = 9.80665;
  sensors::PreintegrationOptions options;
  options.gravity_m_s2 = g;
  const Eigen::Quaterniond q_I_V(Eigen::AngleAxisd(M_PI / 2.0, Eigen::Vector3d::UnitZ()) *
                                 Eigen::AngleAxisd(0.17, Eigen::Vector3d::UnitX()));
  const Eigen::Quaterniond q_k(Eigen::AngleAxisd(0.4, Eigen::Vector3d(1.0, 2.0, 3.0).normalized()));
  // In I: the body rate and the (constant) body velocity of a level turn.
  const Eigen::Vector3d w_I = q_I_V * Eigen::Vector3d(0.0, 0.0, 0.3);
  const Eigen::Vector3d u_I = q_I_V * Eigen::Vector3d(5.0, 0.0, 0.0);
  const Eigen::Vector3d v_k = q_k * u_I, g_W(0.0, 0.0, -g);
  const auto integrate = [&](std::mt19937* random) {
    sensors::PreintegrationOptions o = options;
    sensors::ImuPreintegration pim(noise, o, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
    std::normal_distribution<double> gyro(0.0, noise.GyroSampleSigmaRadS(1.0 / dt));
    std::normal_distribution<double> accel(0.0, noise.accelerometer_noise_density / std::sqrt(dt));
    for (int i = 0; i < 40; ++i) {
      const Eigen::Quaterniond q_t = q_k * geometry::Exp(Eigen::Vector3d(w_I * (i * dt)));
      // Specific force: the turn's centripetal acceleration minus gravity, in I.
      Eigen::Vector3d f = w_I.cross(u_I) - q_t.conjugate() * g_W;
      Eigen::Vector3d w = w_I;
      if (random != nullptr) {
        for (int a = 0; a < 3; ++a) {
          w(a) += gyro(*random);
          f(a) += accel(*random);
        }
      }
      pim.IntegrateStep(w, f, dt);
    }
    return pim;
  };
  const sensors::ImuPreintegration nominal = integrate(nullptr);
  const Eigen::Matrix3d predicted =
      internal::PropagatedVelocityCovariance(nominal, q_k, v_k, q_I_V);
  std::mt19937 random(7);
  const int n = 4000;
  std::vector<Eigen::Vector3d> samples;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (int s = 0; s < n; ++s) {
    const sensors::ImuPreintegration pim = integrate(&random);
    const Eigen::Vector3d u =
        pim.delta_R().transpose() * (q_k.conjugate() * (v_k + g_W * pim.dt_s()) + pim.delta_v());
    samples.push_back(q_I_V.conjugate() * u);
    mean += samples.back() / n;
  }
  Eigen::Matrix3d empirical = Eigen::Matrix3d::Zero();
  for (const Eigen::Vector3d& x : samples)
    empirical += (x - mean) * (x - mean).transpose() / (n - 1);
  std::cout << "predicted variances " << predicted.diagonal().transpose() << ", Monte Carlo "
            << empirical.diagonal().transpose() << " (m/s)^2\n";
  for (int a = 0; a < 3; ++a) {
    EXPECT_NEAR(empirical(a, a) / predicted(a, a), 1.0, 0.1) << a;
  }
  // The attitude's share is visible: the lateral row also sees 5 m/s times the yaw error
  // (measured 1.71e-3 against 1.50e-3 (m/s)^2 for the speed row).
  EXPECT_GT(predicted(1, 1), 1.1 * predicted(0, 0));
}

// ---------------------------------------------------------------------------------------------
// The compressed point group (Eq. W3) against the group it compresses.

TEST(SlidingWindowCompressedPointGroup, KeepsCostGradientAndGaussNewtonMatrix) {
  std::srand(5);
  std::vector<factors::PointToSweepPlaneMeasurement> points;
  for (int i = 0; i < 80; ++i) {
    factors::PointToSweepPlaneMeasurement m;
    m.p_L = 10.0 * Eigen::Vector3d::Random();
    m.motion.dt_s = 0.02 + 0.001 * i;
    m.motion.delta_q = Eigen::Quaterniond(Eigen::AngleAxisd(0.01 * i, Eigen::Vector3d::UnitZ()));
    m.motion.delta_v = Eigen::Vector3d::Random();
    m.motion.delta_p = 0.1 * Eigen::Vector3d::Random();
    m.motion.omega_rad_s = 0.3 * Eigen::Vector3d::Random();
    m.plane_motion.dt_s = 0.03;
    m.plane_L.normal = Eigen::Vector3d::Random().normalized();
    m.plane_L.d = Eigen::Vector3d::Random().x() * 5.0;
    points.push_back(m);
  }
  // Huber: some points are beyond 1 sigma, so the loss rows matter as well.
  const factors::PointToSweepPlaneGroupFactor group(points, Eigen::Vector3d(0.0, 0.0, -kGravity),
                                                    {factors::RobustLoss::kHuber, 1.0});
  const internal::CompressedPointGroup compressed(&group);
  ASSERT_EQ(compressed.parameter_block_sizes(), group.parameter_block_sizes());

  // Parameters: two keyframes, the extrinsic and the offset, away from identity.
  std::vector<Eigen::VectorXd> values;
  for (int size : group.parameter_block_sizes()) {
    Eigen::VectorXd v = Eigen::VectorXd::Random(size);
    if (size == 4) v = Eigen::Quaterniond(Eigen::Vector4d::Random()).normalized().coeffs();
    values.push_back(v);
  }
  std::vector<const double*> parameters;
  for (const Eigen::VectorXd& v : values) parameters.push_back(v.data());

  using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  const auto stacked = [&](const ceres::CostFunction& f, Eigen::VectorXd* r) {
    const int rows = f.num_residuals();
    std::vector<RowMajor> blocks;
    std::vector<double*> jacobians;
    for (int size : f.parameter_block_sizes()) blocks.emplace_back(rows, size);
    for (RowMajor& b : blocks) jacobians.push_back(b.data());
    r->resize(rows);
    EXPECT_TRUE(f.Evaluate(parameters.data(), r->data(), jacobians.data()));
    Eigen::MatrixXd J(rows, internal::CompressedPointGroup::kAmbient);
    Eigen::Index column = 0;
    for (const RowMajor& b : blocks) {
      J.middleCols(column, b.cols()) = b;
      column += b.cols();
    }
    return J;
  };
  Eigen::VectorXd r, rho;
  const Eigen::MatrixXd J = stacked(group, &r);
  const Eigen::MatrixXd R = stacked(compressed, &rho);
  ASSERT_EQ(rho.size(), internal::CompressedPointGroup::kRows);
  ASSERT_GT(r.size(), rho.size());
  const Eigen::MatrixXd H = J.transpose() * J;
  const Eigen::VectorXd g = J.transpose() * r;
  EXPECT_LT((R.transpose() * R - H).norm(), 1e-9 * H.norm());
  EXPECT_LT((R.transpose() * rho - g).norm(), 1e-9 * g.norm());
  EXPECT_NEAR(rho.squaredNorm(), r.squaredNorm(), 1e-9 * r.squaredNorm());
  // The point groups' J^T J is singular (p_k and p_j enter as p_k - p_j): the pivots that
  // vanish leave zero rows, not NaN.
  EXPECT_LT(Eigen::FullPivLU<Eigen::MatrixXd>(H).rank(), internal::CompressedPointGroup::kAmbient);
  EXPECT_TRUE(R.allFinite());

  // Cost only: the same cost.
  Eigen::VectorXd cost_rows(internal::CompressedPointGroup::kRows);
  ASSERT_TRUE(compressed.Evaluate(parameters.data(), cost_rows.data(), nullptr));
  EXPECT_NEAR(cost_rows.squaredNorm(), r.squaredNorm(), 1e-9 * r.squaredNorm());
}

// r(q, x) = R(q) a + x - b: a rotation block and a vector block, as the wheel and GNSS rows.
struct RotatedOffset {
  template <typename T>
  bool operator()(const T* q, const T* x, T* r) const {
    const Eigen::Quaternion<T> rotation = Eigen::Map<const Eigen::Quaternion<T>>(q);
    Eigen::Map<geometry::Vector3<T>> residual(r);
    residual = rotation * Eigen::Vector3d(1.0, -2.0, 0.5).cast<T>() +
               Eigen::Map<const geometry::Vector3<T>>(x) -
               Eigen::Vector3d(0.3, 0.1, -0.2).cast<T>();
    return true;
  }
};

struct NeverEvaluates {
  template <typename T>
  bool operator()(const T*, T*) const {
    return false;
  }
};

// "Linearized once per pass" for any cost function: at the parameters it is built at it returns the
// cost function's rows and Jacobians; elsewhere the first-order model, which agrees with the cost
// function to second order.
TEST(SlidingWindowLinearizedCost, IsTheFirstOrderModelAtItsParameters) {
  ceres::AutoDiffCostFunction<RotatedOffset, 3, 4, 3> cost(new RotatedOffset);
  Eigen::Quaterniond q =
      Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()));
  Eigen::Vector3d x(0.4, -0.3, 1.2);
  const std::vector<double*> blocks = {q.coeffs().data(), x.data()};
  const internal::LinearizedCost<> linearized(cost, blocks, "the test cost");
  EXPECT_EQ(linearized.num_residuals(), 3);
  EXPECT_EQ(linearized.parameter_block_sizes(), cost.parameter_block_sizes());

  using Jacobian = Eigen::Matrix<double, 3, Eigen::Dynamic, Eigen::RowMajor>;
  const auto evaluate = [&blocks](const ceres::CostFunction& f, Eigen::Vector3d* r, Jacobian* Jq,
                                  Jacobian* Jx) {
    Jq->resize(3, 4);
    Jx->resize(3, 3);
    double* jacobians[] = {Jq->data(), Jx->data()};
    return f.Evaluate(blocks.data(), r->data(), jacobians);
  };
  Eigen::Vector3d r0, r0_lin;
  Jacobian Jq, Jx, Jq_lin, Jx_lin;
  ASSERT_TRUE(evaluate(cost, &r0, &Jq, &Jx));
  ASSERT_TRUE(evaluate(linearized, &r0_lin, &Jq_lin, &Jx_lin));
  EXPECT_LT((r0_lin - r0).norm(), 1e-15);
  EXPECT_LT((Jq_lin - Jq).norm(), 1e-15);
  EXPECT_LT((Jx_lin - Jx).norm(), 1e-15);

  // A step dx in the ambient coordinates: the model is r0 + J dx exactly, and it misses the
  // cost function by second-order terms only (half the step, a quarter of the miss).
  const Eigen::Vector4d q0 = q.coeffs();
  const Eigen::Vector3d x0 = x;
  const Eigen::Vector4d dq(1e-3, -1e-3, 2e-3, -1e-3);
  const Eigen::Vector3d dx(1e-3, 2e-3, -1e-3);
  const auto miss = [&](double step) {
    q.coeffs() = q0 + step * dq;
    x = x0 + step * dx;
    Eigen::Vector3d r, r_lin;
    Jacobian Jq_at, Jx_at;
    EXPECT_TRUE(evaluate(cost, &r, &Jq_at, &Jx_at));
    EXPECT_TRUE(evaluate(linearized, &r_lin, &Jq_lin, &Jx_lin));
    EXPECT_LT((r_lin - (r0 + step * (Jq * dq + Jx * dx))).norm(), 1e-15);
    EXPECT_LT((Jq_lin - Jq).norm(), 1e-15);  // the Jacobian of x0
    return (r_lin - r).norm();
  };
  const double full = miss(1.0);
  const double half = miss(0.5);
  EXPECT_GT(full, 1e-7);  // not the cost function itself
  EXPECT_NEAR(full / half, 4.0, 0.2);
  q.coeffs() = q0;
  x = x0;

  ceres::AutoDiffCostFunction<NeverEvaluates, 1, 3> failing(new NeverEvaluates);
  std::vector<double*> x_only = {x.data()};
  try {
    internal::LinearizedCost<>(failing, x_only, "a wheel factor");
    FAIL() << "expected autocal::Error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("a wheel factor cannot be evaluated"), std::string::npos);
  }
}

// Eq. W4: with a loss, the rows and Jacobian at x0 are those Ceres gives the solver for the
// block with that loss (its correction for rho'' <= 0), so the cost's gradient and Gauss-Newton
// matrix at x0 are the robust ones; away from x0 the weight stays the one at x0.
TEST(SlidingWindowLinearizedCost, HoldsTheLossWeightOfItsParameters) {
  ceres::AutoDiffCostFunction<RotatedOffset, 3, 4, 3> cost(new RotatedOffset);
  Eigen::Quaterniond q(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()));
  Eigen::Vector3d x(0.4, -0.3, 1.2);
  const std::vector<double*> blocks = {q.coeffs().data(), x.data()};
  for (const std::string name : {"huber:0.5", "cauchy:0.5", "huber:100"}) {
    SCOPED_TRACE(name);
    const std::unique_ptr<ceres::LossFunction> loss(
        factors::MakeLossFunction(factors::ParseLossOptions(name)));
    const internal::LinearizedCost<> linearized(cost, blocks, "the test cost", loss.get());

    // What Ceres' solver sees for the block with the loss at x0.
    ceres::Problem::Options options;
    options.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    ceres::Problem problem(options);
    const ceres::ResidualBlockId id = problem.AddResidualBlock(&cost, loss.get(), blocks);
    Eigen::Vector3d r_ceres, r_held;
    Eigen::Matrix<double, 3, 4, Eigen::RowMajor> Jq_ceres, Jq_held;
    Eigen::Matrix<double, 3, 3, Eigen::RowMajor> Jx_ceres, Jx_held;
    double* ceres_jacobians[] = {Jq_ceres.data(), Jx_ceres.data()};
    double* held_jacobians[] = {Jq_held.data(), Jx_held.data()};
    double robust_cost = 0.0;
    ASSERT_TRUE(
        problem.EvaluateResidualBlock(id, true, &robust_cost, r_ceres.data(), ceres_jacobians));
    ASSERT_TRUE(linearized.Evaluate(blocks.data(), r_held.data(), held_jacobians));
    EXPECT_LT((r_held - r_ceres).norm(), 1e-14);
    EXPECT_LT((Jq_held - Jq_ceres).norm(), 1e-14);
    EXPECT_LT((Jx_held - Jx_ceres).norm(), 1e-14);

    // The weight sqrt(rho'(|r0|^2)) of the plain rows: below 1 where the loss bites.
    Eigen::Vector3d r0;
    ASSERT_TRUE(cost.Evaluate(blocks.data(), r0.data(), nullptr));
    const double weight = r_held.norm() / r0.norm();
    if (name == "huber:100") {
      EXPECT_NEAR(weight, 1.0, 1e-15);
    } else {
      EXPECT_LT(weight, 0.9);
    }
    // Away from x0 the model keeps that weight: r = w (r0 + J dx).
    const Eigen::Vector3d x0 = x;
    x += Eigen::Vector3d(0.2, -0.1, 0.3);
    Eigen::Vector3d r_far;
    ASSERT_TRUE(linearized.Evaluate(blocks.data(), r_far.data(), nullptr));
    EXPECT_LT((r_far - weight * (r0 + Eigen::Vector3d(0.2, -0.1, 0.3))).norm(), 1e-14);
    x = x0;
  }
}

// ---------------------------------------------------------------------------------------------
// A simulated urban drive.

using test::TrueKeyframe;

struct CalibrationErrors {
  double rotation_deg, translation_m, offset_ms, radius_left_mm, radius_right_mm, track_width_mm,
      lever_arm_m;
};

CalibrationErrors ErrorsOf(const sensors::Calibration& c, const sensors::Calibration& truth) {
  return {geometry::AngularDistance(c.q_I_L, truth.q_I_L) * kRadToDeg,
          (c.p_I_L - truth.p_I_L).norm(),
          1e3 * std::abs(c.time_offset_lidar_imu_s - truth.time_offset_lidar_imu_s),
          1e3 * std::abs(c.wheel_radius_left_m - truth.wheel_radius_left_m),
          1e3 * std::abs(c.wheel_radius_right_m - truth.wheel_radius_right_m),
          1e3 * std::abs(c.track_width_m - truth.track_width_m),
          (c.p_I_A - truth.p_I_A).norm()};
}

std::ostream& operator<<(std::ostream& os, const CalibrationErrors& e) {
  return os << "q_I_L " << e.rotation_deg << " deg, p_I_L " << e.translation_m << " m, offset "
            << e.offset_ms << " ms, radii " << e.radius_left_mm << " / " << e.radius_right_mm
            << " mm, track " << e.track_width_mm << " mm, p_I_A " << e.lever_arm_m << " m";
}

// A 30 s urban drive (16 beams, default noise, all sensors; seed 7: straight driving, then a
// roundabout from 18 s), simulated once for the suite and fed to the estimator in arrival
// order from the true state at 10 s, so that the 20 s streamed contain the turn that makes the
// accelerometer bias and the extrinsic observable.
class SlidingWindowUrban : public ::testing::Test {
 protected:
  struct TrajectoryErrors {
    double max_position_error_m = 0.0;
    double rms_position_error_m = 0.0;
    double max_rotation_error_deg = 0.0;
    double rms_rotation_error_deg = 0.0;
  };
  struct Run : TrajectoryErrors {
    std::vector<SlidingWindowState> trajectory;
    std::vector<SlidingWindowState> smoothed;  // with options.smoothing
    // With options.smoothing: smoothed at the window's own calibration given explicitly, and
    // at it with the lever arm moved 10 cm along x.
    std::vector<SlidingWindowState> smoothed_at_own, smoothed_at_moved;
    TrajectoryErrors smoothed_errors;
    sensors::Calibration calibration;
    CalibrationCovariance covariance;
    SlidingWindowCounters counters;
    int max_window = 0;
    // Per update: solve passes (Eq. W6), plane lookups, associated points and whether the
    // extrinsic had settled (the settled partner walk).
    std::vector<int> passes;
    std::vector<int> lookups;
    std::vector<int> points;
    std::vector<int> settled;
  };

  static TrajectoryErrors TrajectoryErrorsOf(const std::vector<SlidingWindowState>& trajectory) {
    TrajectoryErrors out;
    double sum_sq = 0.0;
    double sum_sq_deg = 0.0;
    for (const SlidingWindowState& x : trajectory) {
      const SlidingWindowState truth = TrueKeyframe(log_->imu, x.t_ns);
      const double e = (x.p_W_I - truth.p_W_I).norm();
      const double e_deg = geometry::AngularDistance(x.q_W_I, truth.q_W_I) * kRadToDeg;
      sum_sq += e * e;
      sum_sq_deg += e_deg * e_deg;
      out.max_position_error_m = std::max(out.max_position_error_m, e);
      out.max_rotation_error_deg = std::max(out.max_rotation_error_deg, e_deg);
    }
    const double n = static_cast<double>(trajectory.size());
    out.rms_position_error_m = std::sqrt(sum_sq / n);
    out.rms_rotation_error_deg = std::sqrt(sum_sq_deg / n);
    return out;
  }

  static std::ostream& Print(std::ostream& os, const TrajectoryErrors& e) {
    return os << "position error max " << e.max_position_error_m << " m, rms "
              << e.rms_position_error_m << " m, rotation error max " << e.max_rotation_error_deg
              << " deg, rms " << e.rms_rotation_error_deg << " deg";
  }

  static void SetUpTestSuite() {
    sim_options_ = new sim::SimulationOptions;
    sim_options_->scenario = sim::ScenarioType::kUrban;
    sim_options_->duration_s = 30.0;
    sim_options_->seed = 7;
    sim_options_->lidar.config.num_beams = 16;
    simulator_ = new sim::Simulator(*sim_options_);
    log_ = new sim::SimulatedLog(test::CachedSimulatedLog(*simulator_));
  }
  static void TearDownTestSuite() {
    delete log_;
    delete simulator_;
    delete sim_options_;
  }

  static SlidingWindowOptions Options() {
    const io::SensorsConfig config = simulator_->sensors_config();
    SlidingWindowOptions options;
    options.imu = config.imu;
    options.wheel = *config.wheel;
    options.enu_origin_lla =
        Eigen::Vector3d(sim_options_->gnss.origin_lat_deg, sim_options_->gnss.origin_lon_deg,
                        sim_options_->gnss.origin_alt_m);
    options.pairing.max_residuals_per_sweep = 400;  // keeps the suite fast; the benchmark uses 2000
    return options;
  }

  static Run Estimate(const sensors::Calibration& start, const SlidingWindowOptions& options) {
    const sim::SimulatedLog& log = *log_;
    const int64_t t0 = log.imu.samples.front().t_ns + SecondsToNs(kStartS);
    SlidingWindowEstimator estimator(options, start, TrueKeyframe(log.imu, t0));

    // Everything in arrival order: a sweep arrives when its last point is measured. Wheel
    // and GNSS samples before the initial state, and sweeps whose keyframe would precede
    // it, belong to no interval.
    enum Kind { kImu, kWheel, kGnss, kSweep };
    std::vector<std::tuple<int64_t, int, size_t>> events;
    for (size_t i = 0; i < log.imu.samples.size(); ++i) {
      events.emplace_back(log.imu.samples[i].t_ns, kImu, i);
    }
    for (size_t i = 0; i < log.wheel.size(); ++i) {
      if (log.wheel[i].t_ns > t0) events.emplace_back(log.wheel[i].t_ns, kWheel, i);
    }
    for (size_t i = 0; i < log.gnss.fixes.size(); ++i) {
      if (log.gnss.fixes[i].t_ns > t0) events.emplace_back(log.gnss.fixes[i].t_ns, kGnss, i);
    }
    for (size_t i = 0; i < log.sweeps.size(); ++i) {
      if (log.sweeps[i].t_ns < t0 + 50'000'000) continue;
      events.emplace_back(log.sweeps[i].t_ns + SecondsToNs(log.sweeps[i].cloud.time_s.maxCoeff()),
                          kSweep, i);
    }
    std::stable_sort(events.begin(), events.end(),
                     [](const auto& a, const auto& b) { return std::get<0>(a) < std::get<0>(b); });

    Run run;
    for (const auto& [t, kind, i] : events) {
      switch (kind) {
        case kImu:
          estimator.AddImu(log.imu.samples[i]);
          break;
        case kWheel:
          estimator.AddWheel(log.wheel[i]);
          break;
        case kGnss:
          estimator.AddGnss(log.gnss.fixes[i]);
          break;
        default:
          estimator.AddSweep(log.sweeps[i]);
          break;
      }
      run.max_window = std::max(run.max_window, estimator.window_size());
      // A sweep is processed once the IMU covers it, so one call makes at most one update.
      EXPECT_LE(estimator.counters().updates, static_cast<int64_t>(run.passes.size()) + 1);
      if (estimator.counters().updates > static_cast<int64_t>(run.passes.size())) {
        run.passes.push_back(estimator.last_update_timing().solver_passes);
        run.lookups.push_back(estimator.last_update_timing().plane_lookups);
        run.points.push_back(estimator.last_associated_points());
        run.settled.push_back(estimator.last_update_timing().extrinsic_settled ? 1 : 0);
      }
    }
    run.trajectory = estimator.Trajectory();
    run.calibration = estimator.calibration();
    run.counters = estimator.counters();
    run.covariance = estimator.ComputeCalibrationCovariance();
    static_cast<TrajectoryErrors&>(run) = TrajectoryErrorsOf(run.trajectory);
    Print(std::cout << run.trajectory.size() << " keyframes, ", run) << "\n";
    if (options.smoothing) {
      run.smoothed = estimator.SmoothedTrajectory();
      run.smoothed_at_own = estimator.SmoothedTrajectory(estimator.calibration());
      sensors::Calibration moved = estimator.calibration();
      moved.p_I_A.x() += 0.1;
      run.smoothed_at_moved = estimator.SmoothedTrajectory(moved);
      run.smoothed_errors = TrajectoryErrorsOf(run.smoothed);
      Print(std::cout << "smoothed: ", run.smoothed_errors) << "\n";
    }
    std::cout << "start:     " << ErrorsOf(start, simulator_->true_calibration()) << "\n"
              << "estimated: " << ErrorsOf(run.calibration, simulator_->true_calibration()) << "\n";
    return run;
  }

  static void ExpectValidCovariance(const CalibrationCovariance& covariance) {
    ASSERT_FALSE(covariance.names.empty());
    EXPECT_EQ(covariance.names.front(), "q_I_L");
    const Eigen::MatrixXd& P = covariance.covariance;
    ASSERT_TRUE(P.allFinite());
    EXPECT_LT((P - P.transpose()).norm(), 1e-9 * P.norm());
    EXPECT_GT(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(P).eigenvalues().minCoeff(),
              -1e-12 * P.norm());
    for (size_t b = 0; b < covariance.names.size(); ++b) {
      const int i = covariance.offsets[b];
      std::cout << covariance.names[b] << " sigma " << std::sqrt(P(i, i)) << "\n";
    }
  }

  static constexpr double kStartS = 10.0;
  static sim::SimulationOptions* sim_options_;
  static sim::Simulator* simulator_;
  static sim::SimulatedLog* log_;
};

sim::SimulationOptions* SlidingWindowUrban::sim_options_ = nullptr;
sim::Simulator* SlidingWindowUrban::simulator_ = nullptr;
sim::SimulatedLog* SlidingWindowUrban::log_ = nullptr;

// Started at the true calibration with every block estimated: the window tracks the truth
// (GNSS has outages) and the calibration stays near it.
TEST_F(SlidingWindowUrban, TracksTruthFromTrueCalibration) {
  const SlidingWindowOptions options = Options();
  const sensors::Calibration& truth = simulator_->true_calibration();
  const Run run = Estimate(truth, options);
  const CalibrationErrors e = ErrorsOf(run.calibration, truth);
  EXPECT_EQ(run.max_window, options.window_size);
  EXPECT_GT(run.trajectory.size(), 190u);
  EXPECT_EQ(run.counters.late, 0);
  // Measured: 0.066 m max, 0.032 m rms, 0.084 deg; q_I_L 0.023 deg, p_I_L 4.8 cm, offset
  // 0.48 ms, radii 0.004 / 0.027 mm, track 1.0 mm, lever arm 1.8 cm.
  EXPECT_LT(run.max_position_error_m, 0.2);
  EXPECT_LT(run.rms_position_error_m, 0.1);
  EXPECT_LT(run.max_rotation_error_deg, 0.15);
  EXPECT_LT(e.rotation_deg, 0.3);
  EXPECT_LT(e.translation_m, 0.1);
  EXPECT_LT(e.offset_ms, 1.5);
  EXPECT_LT(std::max(e.radius_left_mm, e.radius_right_mm), 0.1);
  EXPECT_LT(e.track_width_mm, 5.0);
  EXPECT_LT(e.lever_arm_m, 0.12);
  ExpectValidCovariance(run.covariance);
}

// The yaw-rate rows read the body rate about the axis the keyframes' rates turn about (Eq. K13c
// of docs/keyframe_factors.md), so a mount held with its tilt 5 deg off (rolled about V's
// forward axis) leaves the track where the true mount does. Read about V's up axis, the rows
// see cos(5 deg) of the yaw rate and the track comes out b e^2 / 2 = 6 mm long.
TEST_F(SlidingWindowUrban, TheYawRowsDoNotDependOnTheMountsTilt) {
  const sensors::Calibration& truth = simulator_->true_calibration();
  sensors::Calibration tilted = truth;
  tilted.q_I_V = truth.q_I_V * geometry::Exp(Eigen::Vector3d(5.0 * kDegToRad, 0.0, 0.0));
  SlidingWindowOptions options = Options();
  ASSERT_FALSE(options.estimate.vehicle_frame);  // the mount is held where it starts
  const auto track_error_mm = [&](const sensors::Calibration& start) {
    return 1e3 * (Estimate(start, options).calibration.track_width_m - truth.track_width_m);
  };
  const double from_truth = track_error_mm(truth);
  const double about_axis = track_error_mm(tilted);
  options.wheel_rows.max_turning_axis_error_deg = 0.0;
  const double about_up = track_error_mm(tilted);
  std::cout << "track error: true mount " << from_truth << " mm, tilted mount " << about_axis
            << " mm (about V's up axis " << about_up << " mm)\n";
  EXPECT_LT(std::abs(about_axis - from_truth), 1.0);
  EXPECT_GT(about_up - about_axis, 4.0);
}

// The lateral rows take the rear axle's slip that options.wheel states (Eq. K6c): with the road
// car's (1 cm/s straight, 0.3 deg/(m/s^2) in a turn) the mount's yaw, which the straights fix, is
// stated well below its sigma under the platform defaults (5 cm/s at every sample), above it with
// the straight 1 cm/s alone at every sample (the turns' slip loosens their rows), and its error
// stays inside three of the stated sigmas.
TEST_F(SlidingWindowUrban, TheMountsYawTakesTheStatedSlip) {
  const sensors::Calibration& truth = simulator_->true_calibration();
  SlidingWindowOptions options = Options();
  options.wheel_rows.non_holonomic = true;
  options.estimate.vehicle_frame = true;
  ASSERT_EQ(options.wheel.cornering_compliance_rad_per_m_s2,
            sim::RoadCarWheelConfig().cornering_compliance_rad_per_m_s2);
  const auto yaw = [&](const SlidingWindowOptions& o) {
    const Run run = Estimate(truth, o);
    const auto it = std::find(run.covariance.names.begin(), run.covariance.names.end(), "q_I_V");
    if (it == run.covariance.names.end()) {
      ADD_FAILURE() << "no q_I_V in the window's covariance";
      return std::pair{0.0, 0.0};
    }
    const int i = run.covariance.offsets[static_cast<size_t>(it - run.covariance.names.begin())];
    // About V's up axis: the right perturbation of q_I_V, q_truth = q Exp(delta).
    const double error_deg =
        geometry::Log(run.calibration.q_I_V.conjugate() * truth.q_I_V).z() * kRadToDeg;
    return std::pair{error_deg, std::sqrt(run.covariance.covariance(i + 2, i + 2)) * kRadToDeg};
  };
  const auto [stated_error_deg, stated_sigma_deg] = yaw(options);
  options.wheel.cornering_compliance_rad_per_m_s2 = 0.0;
  const auto [straight_error_deg, straight_sigma_deg] = yaw(options);
  options.wheel.lateral_slip_sigma_m_s = sensors::WheelConfig().lateral_slip_sigma_m_s;
  const auto [default_error_deg, default_sigma_deg] = yaw(options);
  std::cout << "mount yaw: stated slip " << stated_error_deg << " deg at sigma " << stated_sigma_deg
            << " deg, the straight slip alone " << straight_error_deg << " deg at sigma "
            << straight_sigma_deg << " deg, platform defaults " << default_error_deg
            << " deg at sigma " << default_sigma_deg << " deg\n";
  EXPECT_LT(stated_sigma_deg, 0.6 * default_sigma_deg);
  EXPECT_GT(stated_sigma_deg, 1.02 * straight_sigma_deg);
  EXPECT_LT(std::abs(stated_error_deg), 3.0 * stated_sigma_deg);
}

// Started at the simulator's nominal calibration (3.6 deg, 2 cm, 2.8 ms off): the point pairs
// between window sweeps move with the extrinsic and offset (docs/sliding_window.md,
// "Pairing points with planes"), so the window tracks the truth and moves the calibration to it.
TEST_F(SlidingWindowUrban, TracksTruthAndCalibratesFromNominal) {
  const sensors::Calibration& truth = simulator_->true_calibration();
  const sensors::Calibration& nominal = simulator_->nominal_calibration();
  SlidingWindowOptions options = Options();
  options.smoothing = true;
  const Run run = Estimate(nominal, options);
  const CalibrationErrors before = ErrorsOf(nominal, truth);
  const CalibrationErrors after = ErrorsOf(run.calibration, truth);
  // Measured: 0.056 m max, 0.031 m rms, 0.099 deg (from the true calibration 0.066 m, 0.032 m,
  // 0.084 deg); q_I_L 3.6 -> 0.025 deg, p_I_L 1.9 -> 4.0 cm (mostly the height, which planar
  // driving does not excite), offset 2.8 -> 0.72 ms, radii 3.5 / 2.6 -> 0.30 / 0.31 mm, track
  // 20 -> 2.5 mm, lever arm 4.6 -> 1.6 cm (1.8 cm from the true calibration: 30 s of this
  // drive barely observe it).
  EXPECT_LT(run.max_position_error_m, 0.2);
  EXPECT_LT(run.rms_position_error_m, 0.1);
  EXPECT_LT(run.max_rotation_error_deg, 0.4);
  EXPECT_LT(after.rotation_deg, 0.3);
  EXPECT_LT(after.rotation_deg, 0.1 * before.rotation_deg);
  EXPECT_LT(after.translation_m, 0.1);
  EXPECT_LT(after.offset_ms, 1.5);
  EXPECT_LT(after.radius_left_mm, 0.3 * before.radius_left_mm);
  EXPECT_LT(after.radius_right_mm, 0.3 * before.radius_right_mm);
  EXPECT_LT(after.track_width_mm, 0.3 * before.track_width_mm);
  EXPECT_LT(after.lever_arm_m, 0.1);
  ExpectValidCovariance(run.covariance);

  // The smoothed trajectory (docs/sliding_window.md, "Smoothing"): the same keyframes, the
  // window's unchanged, the marginalized ones carried back from the final window. With the
  // extrinsic-aware gate the filtered trajectory from the nominal start is nearly as close to the
  // truth as from the true calibration; the smoother takes it closer still: measured position
  // rms 3.14 -> 2.13 cm, rotation rms 0.051 -> 0.027 deg. Its conditionals were
  // formed while the calibration was still degrees off, and with other residual counts the
  // smoothed position came out up to 10 % worse than the filtered one (docs, "Status and
  // known limitations"); the check is that it stays within that.
  ASSERT_EQ(run.smoothed.size(), run.trajectory.size());
  for (size_t i = 0; i < run.smoothed.size(); ++i) {
    ASSERT_EQ(run.smoothed[i].t_ns, run.trajectory[i].t_ns);
  }
  for (size_t i = run.smoothed.size() - options.window_size; i < run.smoothed.size(); ++i) {
    EXPECT_EQ(run.smoothed[i].p_W_I, run.trajectory[i].p_W_I);
    EXPECT_EQ(run.smoothed[i].q_W_I.coeffs(), run.trajectory[i].q_W_I.coeffs());
  }
  EXPECT_LT(run.smoothed_errors.rms_position_error_m, 1.1 * run.rms_position_error_m);
  EXPECT_LT(run.smoothed_errors.rms_rotation_error_deg, 1.1 * run.rms_rotation_error_deg);
  EXPECT_LT(run.smoothed_errors.rms_rotation_error_deg, 0.1);
  // Given a calibration (a held one, Eq. C1): at the window's own the same pass to the bit; at
  // one whose lever arm moved, every marginalized keyframe follows through its conditional
  // while the window's keyframes stay.
  ASSERT_EQ(run.smoothed_at_own.size(), run.smoothed.size());
  ASSERT_EQ(run.smoothed_at_moved.size(), run.smoothed.size());
  const size_t marginalized = run.smoothed.size() - static_cast<size_t>(options.window_size);
  double moved_m = 0.0;
  for (size_t i = 0; i < run.smoothed.size(); ++i) {
    EXPECT_EQ(run.smoothed_at_own[i].p_W_I, run.smoothed[i].p_W_I);
    EXPECT_EQ(run.smoothed_at_own[i].q_W_I.coeffs(), run.smoothed[i].q_W_I.coeffs());
    const double d = (run.smoothed_at_moved[i].p_W_I - run.smoothed[i].p_W_I).norm();
    if (i >= marginalized) {
      EXPECT_EQ(d, 0.0) << i;
    } else {
      moved_m = std::max(moved_m, d);
    }
  }
  EXPECT_GT(moved_m, 0.001);
}

// The extrinsic-aware gate (docs/sliding_window.md, "Partner walk"): from the nominal calibration
// the window converges whatever the residual count. With the gate fixed at max_point_to_plane_m the
// outcome was chance: 370 and 430 residual points per sweep ended 1.49 and 1.55 m rms from the
// truth, with q_I_L still 2-2.6 deg off. Measured: 0.035 / 0.031 m rms, q_I_L 0.052 / 0.055 deg.
TEST_F(SlidingWindowUrban, ConvergesFromNominalWhateverTheResidualCount) {
  const sensors::Calibration& truth = simulator_->true_calibration();
  for (int residuals : {370, 430}) {
    SCOPED_TRACE(residuals);
    SlidingWindowOptions options = Options();
    options.pairing.max_residuals_per_sweep = residuals;
    const Run run = Estimate(simulator_->nominal_calibration(), options);
    const CalibrationErrors after = ErrorsOf(run.calibration, truth);
    EXPECT_LT(run.max_position_error_m, 0.2);
    EXPECT_LT(run.rms_position_error_m, 0.1);
    EXPECT_LT(run.max_rotation_error_deg, 0.4);
    EXPECT_LT(after.rotation_deg, 0.3);
  }
}

double Mean(const std::vector<int>& values, size_t begin, size_t end) {
  double sum = 0.0;
  for (size_t i = begin; i < end; ++i) sum += values[i];
  return sum / static_cast<double>(end - begin);
}

// Eq. W6 (docs/sliding_window.md, "A second pass only for the groups that moved"): from the nominal
// calibration, with the tolerance 0 every update takes both passes; with the default some do and
// some do not, and more of them while the extrinsic converges than at the end. On planes of five
// map points, whose pairs move more often than the default ten's (1.05, 1.18 and 1.00 there), so
// that both kinds of update are common. Measured: all 2; 1.07 passes per update, 1.20 over the
// first quarter, 1.00 over the last.
TEST_F(SlidingWindowUrban, TakesASecondPassOnlyWhenTheFirstMovedASweepPair) {
  const sensors::Calibration& nominal = simulator_->nominal_calibration();
  SlidingWindowOptions adaptive_options = Options();
  adaptive_options.pairing.plane_map.num_neighbors = 5;
  SlidingWindowOptions options = adaptive_options;
  options.linearization.relinearization_tolerance_m = 0.0;
  const Run always = Estimate(nominal, options);
  ASSERT_FALSE(always.passes.empty());
  for (int passes : always.passes) EXPECT_EQ(passes, 2);

  const Run adaptive = Estimate(nominal, adaptive_options);
  const size_t n = adaptive.passes.size();
  ASSERT_GT(n, 100u);
  for (int passes : adaptive.passes) EXPECT_TRUE(passes == 1 || passes == 2);
  const double first = Mean(adaptive.passes, 0, n / 4);
  const double last = Mean(adaptive.passes, n - n / 4, n);
  std::cout << "passes per update " << Mean(adaptive.passes, 0, n) << ", first quarter " << first
            << ", last quarter " << last << "\n";
  EXPECT_LT(Mean(adaptive.passes, 0, n), 1.8);
  EXPECT_GT(Mean(adaptive.passes, 0, n), 1.05);
  EXPECT_GT(first, last);
  // The accuracy with the default: TracksTruthAndCalibratesFromNominal.
}

// Partners whose pairs last two updates, the list before the farthest became ±window_size:
// the shortcuts below save most where a point's tries repeat. With the default list a settled
// keyframe's pairs last one update each, and both shortcuts have less to save.
std::vector<int> TwoUpdatePartners() { return {-9, 9, -5, 5, -8, 8, -3, 3, -2, 2}; }

// Kept tries ("Reuse between updates"): against a fresh association at every update (both
// tolerances 0) the window pairs as many points, with a fraction of the lookups, and tracks
// the truth as well. (The maps' generations in a try matter from the nominal calibration:
// without them TracksTruthAndCalibratesFromNominal ended with q_I_L 0.95 deg.) Measured (from
// the second quarter on): 561 against 599 points per update, 0.89k against 2.5k lookups;
// position rms 0.0275 against 0.0276 m. With the settled walk's partners 5 keyframes apart
// instead of the window's 9 it was 1457 against 1469 points, 0.84k against 5.1k lookups: a far
// partner's lookup that found no plane is kept while its try holds, where a fresh association
// tries again after each solve. With the default partners (±10 first): 347 against 366 points,
// 0.88k against 1.5k lookups, position rms 0.0257 against 0.0260 m.
TEST_F(SlidingWindowUrban, KeptTriesPairLikeAFreshAssociation) {
  const sensors::Calibration& truth = simulator_->true_calibration();
  SlidingWindowOptions fresh_options = Options();
  fresh_options.pairing.partner_offsets = TwoUpdatePartners();
  fresh_options.window_pairing.reassociation_tolerance_m = 0.0;
  fresh_options.window_pairing.map_rebuild_tolerance_m = 0.0;
  const Run fresh = Estimate(truth, fresh_options);
  SlidingWindowOptions kept_options = Options();
  kept_options.pairing.partner_offsets = TwoUpdatePartners();
  const Run kept = Estimate(truth, kept_options);
  ASSERT_EQ(kept.points.size(), fresh.points.size());
  const size_t n = kept.points.size();
  const double kept_points = Mean(kept.points, n / 4, n);
  const double fresh_points = Mean(fresh.points, n / 4, n);
  const double kept_lookups = Mean(kept.lookups, n / 4, n);
  const double fresh_lookups = Mean(fresh.lookups, n / 4, n);
  std::cout << "points per update " << kept_points << " kept, " << fresh_points
            << " fresh; lookups " << kept_lookups << " kept, " << fresh_lookups << " fresh\n";
  EXPECT_NEAR(kept_points, fresh_points, 0.08 * fresh_points);
  EXPECT_LT(kept_lookups, 0.4 * fresh_lookups);
  EXPECT_LT(kept.rms_position_error_m, 1.2 * fresh.rms_position_error_m);
  EXPECT_LT(kept.max_rotation_error_deg, 1.2 * fresh.max_rotation_error_deg);
}

// A keyframe with nothing to re-pair is skipped (skip_unchanged_keyframes); walking it
// instead changes nothing: the same lookups, points and estimates at every update, from the
// nominal calibration, with a tolerance of 5 mm so that tries go stale often.
TEST_F(SlidingWindowUrban, SkipsOnlyKeyframesWithNothingToRepair) {
  SlidingWindowOptions skip = Options();
  skip.window_pairing.reassociation_tolerance_m = 0.005;
  SlidingWindowOptions walk_all = skip;
  walk_all.window_pairing.skip_unchanged_keyframes = false;
  const sensors::Calibration& nominal = simulator_->nominal_calibration();
  const Run walked = Estimate(nominal, walk_all);
  const Run skipped = Estimate(nominal, skip);
  EXPECT_EQ(skipped.lookups, walked.lookups);
  EXPECT_EQ(skipped.points, walked.points);
  EXPECT_EQ(skipped.passes, walked.passes);
  ASSERT_EQ(skipped.trajectory.size(), walked.trajectory.size());
  EXPECT_EQ(skipped.trajectory.back().p_W_I, walked.trajectory.back().p_W_I);
  EXPECT_EQ(skipped.calibration.q_I_L.coeffs(), walked.calibration.q_I_L.coeffs());
}

// The settled partner walk (docs/sliding_window.md, "Partner walk"): once the extrinsic rotation
// has settled, a new keyframe's points try only the first settled_partner_count partner offsets
// (the farthest keyframes pairing reaches, ten back and ahead). From the true calibration the
// window settles once it is full and stays so; against every partner tried throughout (the
// count at the list's size) it makes a third of the lookups and tracks the truth as well
// on this 20 s drive. From the nominal calibration it settles only once the extrinsic stops
// moving. Measured: settled in 0.90 of the updates after the first window_size; lookups 0.91k
// against 3.0k per update (from the second quarter on), position rms 0.0263 against 0.0260 m,
// rotation rms 0.024 deg (with the settled partners nine keyframes apart: 0.88, 0.95k against
// 3.0k lookups, 0.0275 against 0.0249 m; five apart: 0.85k against 2.5k lookups, 0.0253 against
// 0.0261 m, 0.033 deg): neighbouring keyframes are tied by the IMU and the far pairs, which
// hold the tilt over a longer drive (OnlineEstimationUrban60s); from nominal, settled in 0.47 of
// the first quarter's updates and all of the last quarter's. Both walks look up every point in
// every partner they walk (max_plane_misses 0): the rule below takes most of the lookups that the
// settled walk saves.
TEST_F(SlidingWindowUrban, PairsWithFewerPartnersOnceTheExtrinsicSettled) {
  const sensors::Calibration& truth = simulator_->true_calibration();
  SlidingWindowOptions settled_options = Options();
  settled_options.window_pairing.max_plane_misses = 0;
  SlidingWindowOptions all_options = settled_options;
  all_options.window_pairing.settled_partner_count =
      static_cast<int>(all_options.pairing.partner_offsets.size());
  const Run all = Estimate(truth, all_options);
  const Run settled = Estimate(truth, settled_options);
  const size_t n = settled.settled.size();
  ASSERT_GT(n, 100u);
  ASSERT_EQ(all.lookups.size(), n);
  const size_t window = static_cast<size_t>(Options().window_size);
  for (size_t i = 0; i < window; ++i) EXPECT_EQ(settled.settled[i], 0) << i;
  std::cout << "settled in " << Mean(settled.settled, window, n)
            << " of the updates after the first window_size\n";
  EXPECT_GT(Mean(settled.settled, window, n), 0.8);
  const double settled_lookups = Mean(settled.lookups, n / 4, n);
  const double all_lookups = Mean(all.lookups, n / 4, n);
  std::cout << "lookups per update " << settled_lookups << " settled, " << all_lookups
            << " every partner\n";
  EXPECT_LT(settled_lookups, 0.5 * all_lookups);
  EXPECT_LT(settled.rms_position_error_m, 1.15 * all.rms_position_error_m);
  EXPECT_LT(settled.max_rotation_error_deg, 1.1 * all.max_rotation_error_deg);

  const Run nominal = Estimate(simulator_->nominal_calibration(), settled_options);
  const size_t m = nominal.settled.size();
  const double first = Mean(nominal.settled, 0, m / 4);
  const double last = Mean(nominal.settled, m - m / 4, m);
  std::cout << "from nominal: settled in " << first << " of the first quarter's updates, " << last
            << " of the last quarter's\n";
  EXPECT_LT(first, last);
}

// max_plane_misses (docs/sliding_window.md, "Points without a plane"): a point whose last
// six lookups found no plane is not looked up again until its own map is rebuilt. From the
// nominal calibration, against looking every point up in every partner it walks, it makes
// fewer lookups, keeps the pairs and tracks the truth as well. Measured where many points find
// no plane: the residual points' range unlimited (residual_max_range_m 0; the default range
// leaves few without one, "Far points") and planes of five map points (the default ten leave
// fewer: 1144 lookups per update against 1193, 1188 points against 1194, q_I_L 0.021 deg
// both): 1190 lookups against 1400, 642 points against 703, q_I_L 0.054 against 0.053 deg at
// the end (1234 against 1413, 673 against 712 before the IMU factor's bias-delta correlation
// took its sign, docs/factors.md F10: which points miss follows the trajectory, so the share
// kept moves with it, here 0.945 to 0.914; the points' share is held above 0.9, the lookups
// below 0.9 and the estimates to the run without the cap) (with the settled partners 5
// keyframes apart instead of 9: 1147 against 1334
// lookups, 1174 against 1187 points; earlier, with two misses: 875 lookups, 1067 points, q_I_L
// 0.118 deg: the points of sparse far ground, which pin the rotation, miss most). With the
// default partners (±10 first): 1216 against 1268 lookups, 596 against 541 points, q_I_L 0.013
// against 0.018 deg.
TEST_F(SlidingWindowUrban, StopsLookingUpPointsWithoutAPlane) {
  const sensors::Calibration& nominal = simulator_->nominal_calibration();
  SlidingWindowOptions capped_options = Options();
  capped_options.pairing.partner_offsets = TwoUpdatePartners();
  capped_options.pairing.residual_max_range_m = 0.0;
  capped_options.pairing.plane_map.num_neighbors = 5;
  SlidingWindowOptions every_options = capped_options;
  every_options.window_pairing.max_plane_misses = 0;
  const Run every = Estimate(nominal, every_options);
  const Run capped = Estimate(nominal, capped_options);
  ASSERT_EQ(capped.lookups.size(), every.lookups.size());
  const size_t n = capped.lookups.size();
  const double capped_lookups = Mean(capped.lookups, 0, n);
  const double every_lookups = Mean(every.lookups, 0, n);
  const double capped_points = Mean(capped.points, 0, n);
  const double every_points = Mean(every.points, 0, n);
  std::cout << "lookups per update " << capped_lookups << " against " << every_lookups
            << ", points " << capped_points << " against " << every_points << "\n";
  EXPECT_LT(capped_lookups, 0.9 * every_lookups);
  EXPECT_GT(capped_points, 0.9 * every_points);
  EXPECT_LT(capped.rms_position_error_m, 1.1 * every.rms_position_error_m);
  EXPECT_LT(capped.rms_rotation_error_deg, 1.1 * every.rms_rotation_error_deg);
  const double capped_q =
      geometry::AngularDistance(capped.calibration.q_I_L, simulator_->true_calibration().q_I_L);
  const double every_q =
      geometry::AngularDistance(every.calibration.q_I_L, simulator_->true_calibration().q_I_L);
  std::cout << "q_I_L error " << capped_q * kRadToDeg << " against " << every_q * kRadToDeg
            << " deg\n";
  EXPECT_LT(capped_q, every_q + 0.01 * kDegToRad);
}

TEST(SlidingWindowSmoothing, NeedsTheOption) {
  SlidingWindowEstimator estimator(FastOptions(), sensors::Calibration(), StillState());
  try {
    estimator.SmoothedTrajectory();
    FAIL() << "expected autocal::Error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("SlidingWindowOptions::smoothing"), std::string::npos);
  }
}

}  // namespace
}  // namespace estimation
}  // namespace autocal
