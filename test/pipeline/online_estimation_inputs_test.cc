// The online estimator's checks that a sensor the problem uses reaches the sliding window
// (src/pipeline/calibration_steps.h) and its keyframe period without the LiDAR
// (src/pipeline/online_without_lidar.h), on hand-made sample lists.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <map>
#include <string>
#include <tuple>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/estimation/sliding_window_blocks.h"
#include "autocal/io/dataset.h"
#include "autocal/pipeline/offline_calibration.h"
#include "autocal/pipeline/online_estimation.h"
#include "pipeline/calibration_steps.h"
#include "pipeline/online_without_lidar.h"
#include "pipeline/residual_groups.h"
#include "pipeline/window_settings.h"

namespace autocal {
namespace pipeline {
namespace {

using ::testing::HasSubstr;

constexpr int64_t kStartNs = 1'700'000'000'000'000'000;

// 100 Hz wheels and 10 Hz fixes over the first `duration_s` seconds.
io::Dataset Logged(double duration_s) {
  io::Dataset dataset;
  dataset.directory = "/data/run7";
  for (int64_t t = 0; t <= static_cast<int64_t>(duration_s * 1e9); t += 10'000'000) {
    sensors::WheelSample w;
    w.t_ns = kStartNs + t;
    dataset.wheel.push_back(w);
    if (t % 100'000'000 == 0) {
      sensors::GnssFix fix;
      fix.t_ns = kStartNs + t;
      dataset.gnss.push_back(fix);
    }
  }
  return dataset;
}

// Wheels logged only while the online estimator initializes (the first 2 s here): the window,
// which starts at 3 s, would never see one, and the result would silently leave them out.
TEST(OnlineEstimationInputs, RefusesSensorsWithNoSampleAfterTheInitialState) {
  const io::Dataset dataset = Logged(2.0);
  const int64_t t0_ns = kStartNs + 3'000'000'000;
  try {
    RequireSamplesAfter(dataset, true, false, t0_ns);
    FAIL() << "wheels that end before the initial state were accepted";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()),
              "dataset /data/run7: wheel.csv: 0 of 201 samples after the online estimator's "
              "initial state at 1700000003000000000 ns (the log's last is at "
              "1700000002000000000 ns); nothing was estimated");
  }
  EXPECT_THROW(RequireSamplesAfter(dataset, false, true, t0_ns), Error);
  // Unused sensors, or samples after the initial state, pass.
  EXPECT_NO_THROW(RequireSamplesAfter(dataset, false, false, t0_ns));
  EXPECT_NO_THROW(RequireSamplesAfter(dataset, true, true, kStartNs + 1'000'000'000));
}

TEST(OnlineEstimationInputs, RefusesSensorsTheWindowAcceptedNothingFrom) {
  const io::Dataset dataset = Logged(5.0);
  estimation::SlidingWindowCounters counters;
  counters.wheel_accepted = 380;
  counters.gnss_accepted = 0;  // every fix late or out of order
  try {
    RequireStreamedSamples(dataset, true, true, counters);
    FAIL() << "a run whose fixes never reached the window was accepted";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), HasSubstr("no GNSS sample reached the sliding window (gnss.csv: 0 of "
                                    "51 samples"));
  }
  EXPECT_NO_THROW(RequireStreamedSamples(dataset, true, false, counters));
  counters.wheel_accepted = 0;
  EXPECT_THROW(RequireStreamedSamples(dataset, true, false, counters), Error);
}

// Fixes every interval_ns, each stamp moved by up to jitter_ns (a fixed pattern).
io::Dataset FixesEvery(int64_t interval_ns, int64_t jitter_ns, int count) {
  io::Dataset dataset;
  dataset.directory = "/data/run8";
  for (int i = 0; i < count; ++i) {
    sensors::GnssFix fix;
    fix.t_ns = kStartNs + i * interval_ns + ((i * 7) % 5 - 2) * jitter_ns / 2;
    dataset.gnss.push_back(fix);
  }
  return dataset;
}

// The keyframe period is the median GNSS interval (jitter and an outage do not move it),
// clamped to [0.05, 0.5] s; the option overrides it.
TEST(OnlineEstimationInputs, KeyframePeriodFollowsTheGnssRate) {
  const OnlineEstimationOptions options;
  EXPECT_EQ(KeyframePeriodWithoutLidar(FixesEvery(100'000'000, 0, 50), options), 100'000'000);
  EXPECT_EQ(KeyframePeriodWithoutLidar(FixesEvery(400'000'000, 0, 50), options), 400'000'000);
  EXPECT_EQ(KeyframePeriodWithoutLidar(FixesEvery(50'000'000, 0, 50), options), 50'000'000);
  EXPECT_EQ(KeyframePeriodWithoutLidar(FixesEvery(20'000'000, 0, 50), options), 50'000'000);
  EXPECT_EQ(KeyframePeriodWithoutLidar(FixesEvery(1'000'000'000, 0, 50), options), 500'000'000);
  io::Dataset outage = FixesEvery(200'000'000, 0, 50);
  for (size_t i = 20; i < outage.gnss.size(); ++i) outage.gnss[i].t_ns += 10'000'000'000;
  EXPECT_EQ(KeyframePeriodWithoutLidar(outage, options), 200'000'000);
  const int64_t jittered =
      KeyframePeriodWithoutLidar(FixesEvery(200'000'000, 20'000'000, 51), options);
  EXPECT_NEAR(static_cast<double>(jittered), 200'000'000.0, 20'000'000.0);
  OnlineEstimationOptions set = options;
  set.keyframe_period_without_lidar_s = 0.25;
  EXPECT_EQ(KeyframePeriodWithoutLidar(FixesEvery(100'000'000, 0, 50), set), 250'000'000);
  try {
    KeyframePeriodWithoutLidar(FixesEvery(100'000'000, 0, 1), options);
    FAIL() << "one fix gave a period";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), HasSubstr("dataset /data/run8: gnss.csv has 1 fix"));
  }
}

// The window reads wheels and fixes on the IMU clock and has no clock blocks: a problem that
// estimates a clock, or a dataset that states one, is refused instead of silently ignored.
TEST(OnlineEstimationInputs, RefusesClockOffsetsTheWindowCannotApply) {
  io::Dataset dataset = Logged(2.0);
  io::Problem problem;
  problem.path = "clocks.yaml";
  EXPECT_NO_THROW(WindowOptions(dataset, problem, true, true, OnlineEstimationOptions()));
  problem.calibration.time_offset_wheel_imu_s.mode = io::BlockMode::kEstimate;
  try {
    WindowOptions(dataset, problem, true, true, OnlineEstimationOptions());
    FAIL() << "an estimated wheel clock was accepted";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), HasSubstr("clocks.yaml: the online estimator does not estimate"));
  }
  EXPECT_NO_THROW(WindowOptions(dataset, problem, false, true, OnlineEstimationOptions()));
  problem.calibration.time_offset_wheel_imu_s.mode = io::BlockMode::kFixed;
  dataset.sensors.nominal_calibration.time_offset_gnss_imu_s = -0.2;
  try {
    WindowOptions(dataset, problem, true, true, OnlineEstimationOptions());
    FAIL() << "a stated GNSS clock offset was ignored";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), HasSubstr("GNSS time offset of -0.2"));
  }
}

// A block whose sigma neither the problem nor sensors.yaml states gets the offline
// calibration's default prior, in the window as in the batch; a stated one wins.
TEST(OnlineEstimationInputs, UnstatedPriorsAreTheOfflineCalibrations) {
  io::Dataset dataset = Logged(10.0);
  io::Problem problem;
  problem.path = "priors.yaml";
  const OfflineCalibrationOptions offline;
  estimation::SlidingWindowOptions w =
      WindowOptions(dataset, problem, true, true, OnlineEstimationOptions());
  EXPECT_EQ(w.calibration_prior.vehicle_rotation_deg, offline.default_rotation_prior_sigma_deg);
  EXPECT_EQ(w.calibration_prior.extrinsic_rotation_deg, offline.default_rotation_prior_sigma_deg);
  EXPECT_EQ(w.calibration_prior.extrinsic_translation_m, offline.default_translation_prior_sigma_m);
  EXPECT_EQ(w.calibration_prior.time_offset_s, offline.default_time_offset_prior_sigma_s);
  EXPECT_EQ(w.calibration_prior.gnss_lever_arm_m, offline.default_translation_prior_sigma_m);
  problem.calibration.T_I_V.rotation = {io::BlockMode::kPrior, Eigen::Vector3d(1.0, 2.0, 0.5)};
  w = WindowOptions(dataset, problem, true, true, OnlineEstimationOptions());
  EXPECT_EQ(w.calibration_prior.vehicle_rotation_deg, 2.0);
}

// A stated sigma whose axes differ stays per axis in the window's prior, as in the batch; one
// sigma on every axis, or a default, is the block's one sigma.
TEST(OnlineEstimationInputs, StatedAxesKeepTheirOwnSigmas) {
  io::Dataset dataset = Logged(10.0);
  io::Problem problem;
  problem.path = "priors.yaml";
  problem.calibration.T_I_V.rotation = {io::BlockMode::kPrior, Eigen::Vector3d(1.0, 2.0, 0.5)};
  problem.calibration.T_I_V.translation = {io::BlockMode::kPrior, Eigen::Vector3d::Constant(0.04)};
  io::VectorBlockInfo antenna;
  antenna.sigma = Eigen::Vector3d(0.02, 0.02, 0.005);
  dataset.sensors.nominal_uncertainty.p_I_A_m = antenna;
  const estimation::SlidingWindowOptions w =
      WindowOptions(dataset, problem, true, true, OnlineEstimationOptions());
  using Id = sensors::CalibrationBlockId;
  const std::map<Id, Eigen::Vector3d>& axes = w.calibration_prior.axis_sigmas;
  ASSERT_EQ(axes.count(Id::kVehicleRotation), 1u);
  EXPECT_EQ(axes.at(Id::kVehicleRotation), Eigen::Vector3d(1.0, 2.0, 0.5));
  ASSERT_EQ(axes.count(Id::kGnssLeverArm), 1u);
  EXPECT_EQ(axes.at(Id::kGnssLeverArm), Eigen::Vector3d(0.02, 0.02, 0.005));
  EXPECT_EQ(axes.count(Id::kVehicleTranslation), 0u);
  EXPECT_EQ(axes.count(Id::kLidarRotation), 0u);
  EXPECT_EQ(w.calibration_prior.vehicle_translation_m, 0.04);
  EXPECT_EQ(estimation::PriorSigmasOf(Id::kVehicleTranslation, w.calibration_prior),
            Eigen::VectorXd::Constant(3, 0.04));
}

// Without the LiDAR the window reads the wheels and fixes moved onto the IMU clock by the
// stated offsets (t_imu = t + offset), and says that it holds them.
TEST(OnlineEstimationInputs, WithoutTheLidarTheStatedClockOffsetsMoveTheStamps) {
  io::Dataset dataset = Logged(2.0);
  dataset.sensors.nominal_calibration.time_offset_wheel_imu_s = 0.25;
  dataset.sensors.nominal_calibration.time_offset_gnss_imu_s = -0.1;
  io::Problem problem;
  problem.sensors.lidar = false;
  problem.calibration.T_I_V.rotation.mode = io::BlockMode::kFixed;
  problem.calibration.T_I_V.translation.mode = io::BlockMode::kFixed;
  sensors::Calibration applied;
  std::vector<std::string> warnings;
  const io::Dataset moved = OnImuClock(dataset, &problem, &applied, &warnings);
  ASSERT_EQ(moved.wheel.size(), dataset.wheel.size());
  EXPECT_EQ(moved.wheel.front().t_ns, dataset.wheel.front().t_ns + 250'000'000);
  EXPECT_EQ(moved.gnss.back().t_ns, dataset.gnss.back().t_ns - 100'000'000);
  EXPECT_EQ(moved.sensors.nominal_calibration.time_offset_wheel_imu_s, 0.0);
  EXPECT_EQ(moved.sensors.nominal_calibration.time_offset_gnss_imu_s, 0.0);
  EXPECT_EQ(applied.time_offset_wheel_imu_s, 0.25);
  EXPECT_EQ(applied.time_offset_gnss_imu_s, -0.1);
  ASSERT_EQ(warnings.size(), 2u);
  EXPECT_THAT(warnings[0], HasSubstr("wheel-IMU time offset is held at 250.0 ms"));
  EXPECT_THAT(warnings[1], HasSubstr("GNSS-IMU time offset is held at -100.0 ms"));
  EXPECT_NO_THROW(WindowOptions(moved, problem, true, true, OnlineEstimationOptions()));
}

// The residual statistics of calibration.yaml: 1000 rows of RMS 1 (a sinusoid, whose median
// |r| is 1: robust sigma 1.48, where Gaussian rows give 1) and 10 at 50 sigma have a plain RMS
// of 5, 10 outlier rows and an RMS of 1 without them; rows of several kinds get the plain
// figures only.
// A span option beyond 1e9 s is refused before any work: in nanoseconds it overflowed, and
// --init_duration_s=1e300 read as an initialization over no sweep at all.
TEST(OnlineEstimationInputs, RefusesSpansBeyondInt64Nanoseconds) {
  io::Dataset dataset = Logged(1.0);
  dataset.wheel.clear();
  for (const int64_t t : {int64_t{0}, int64_t{1'000'000'000}}) {
    sensors::ImuSample sample;
    sample.t_ns = kStartNs + t;
    dataset.imu.push_back(sample);
  }
  io::Problem problem;
  problem.path = "imu_gnss.yaml";
  problem.sensors.lidar = false;
  problem.sensors.wheel = false;
  for (const auto& [duration_s, period_s, message] :
       std::vector<std::tuple<double, double, std::string>>{
           {1e300, 0.0,
            "initialization_duration_s must be a positive number of seconds up to 1e9, "
            "got 1e+300"},
           {30.0, 1e12, "keyframe_period_without_lidar_s must be within [0, 1e9] s, got 1e+12"},
           {30.0, std::nan(""), "keyframe_period_without_lidar_s must be within [0, 1e9] s"}}) {
    OnlineEstimationOptions options;
    options.initialization_duration_s = duration_s;
    options.keyframe_period_without_lidar_s = period_s;
    try {
      EstimateDatasetOnline(dataset, problem, options);
      ADD_FAILURE() << message;
    } catch (const Error& e) {
      EXPECT_THAT(e.what(), HasSubstr(message));
    }
  }
}

TEST(WhitenedStatistics, NameTheOutliersThatCarryTheRms) {
  std::vector<double> rows;
  for (int i = 0; i < 1000; ++i) rows.push_back(std::sin(0.7 * i) * std::sqrt(2.0));
  for (int i = 0; i < 10; ++i) rows.push_back(i % 2 == 0 ? 50.0 : -50.0);
  const std::map<std::string, double> s = WhitenedStatistics(rows, true);
  EXPECT_EQ(s.at("rows"), 1010.0);
  EXPECT_NEAR(s.at("whitened_rms"), std::sqrt((1000.0 + 25000.0) / 1010.0), 0.01);
  EXPECT_NEAR(s.at("whitened_robust_sigma"), 1.4826 * std::sqrt(2.0) * std::sin(M_PI / 4), 0.05);
  EXPECT_EQ(s.at("outlier_rows"), 10.0);
  EXPECT_NEAR(s.at("whitened_rms_without_outliers"), 1.0, 0.01);
  const std::map<std::string, double> plain = WhitenedStatistics(rows, false);
  EXPECT_EQ(plain.size(), 2u);
  EXPECT_TRUE(WhitenedStatistics({}, true).empty());
}

}  // namespace
}  // namespace pipeline
}  // namespace autocal
