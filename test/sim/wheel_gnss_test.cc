// Wheel rates equal the true rear-wheel speeds over the true radii; GNSS fixes converted back
// to ENU match the true antenna position; the simulator is deterministic for a seed.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <GeographicLib/LocalCartesian.hpp>
#include <cmath>
#include <map>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/time.h"
#include "autocal/common/units.h"
#include "autocal/geometry/so3.h"
#include "autocal/sim/simulator.h"
#include "sim/sim_test_util.h"

namespace autocal {
namespace sim {
namespace {

using ::testing::HasSubstr;

class WheelGnssTest : public ::testing::TestWithParam<ScenarioType> {};

// Expected wheel rates from the written truth (T_W_I at the IMU rate): V's velocity and yaw
// rate by central differences, v -+ omega b / 2 over the true radii.
std::map<int64_t, Eigen::Vector2d> ExpectedWheelRates(const Simulator& simulator,
                                                      const io::Trajectory& truth) {
  const sensors::Calibration& c = simulator.true_calibration();
  const geometry::Pose3d T_I_V(c.q_I_V, c.p_I_V);
  std::map<int64_t, Eigen::Vector2d> rates;
  for (size_t k = 1; k + 1 < truth.size(); ++k) {
    const double dt = NsToSeconds(truth[k + 1].t_ns - truth[k - 1].t_ns);
    const geometry::Pose3d prev = truth[k - 1].T_W_I * T_I_V;
    const geometry::Pose3d curr = truth[k].T_W_I * T_I_V;
    const geometry::Pose3d next = truth[k + 1].T_W_I * T_I_V;
    const double forward = (curr.q.conjugate() * ((next.p - prev.p) / dt)).x();
    const double yaw_rate =
        (geometry::Log(Eigen::Quaterniond(prev.q.conjugate() * next.q)) / dt).z();
    rates[truth[k].t_ns] =
        Eigen::Vector2d((forward - 0.5 * c.track_width_m * yaw_rate) / c.wheel_radius_left_m,
                        (forward + 0.5 * c.track_width_m * yaw_rate) / c.wheel_radius_right_m);
  }
  return rates;
}

TEST_P(WheelGnssTest, WheelRatesAreTrueWheelSpeedsOverTrueRadii) {
  const SimulationOptions options = test::SmallLog(GetParam());
  const Simulator exact(options.WithoutNoise());
  const Simulator noisy(options);
  const std::map<int64_t, Eigen::Vector2d> expected =
      ExpectedWheelRates(exact, exact.GenerateImu().truth);
  const sensors::WheelSamples exact_samples = exact.GenerateWheel();
  const sensors::WheelSamples noisy_samples = noisy.GenerateWheel();
  ASSERT_EQ(exact_samples.size(), noisy_samples.size());
  ASSERT_GT(exact_samples.size(), 2000u);
  double worst = 0.0, sum_sq = 0.0;
  int64_t compared = 0;
  for (size_t i = 0; i < exact_samples.size(); ++i) {
    const auto it = expected.find(exact_samples[i].t_ns);
    if (it == expected.end()) continue;
    const Eigen::Vector2d measured(exact_samples[i].left_rad_s, exact_samples[i].right_rad_s);
    const double error = (measured - it->second).cwiseAbs().maxCoeff();
    EXPECT_LT(error, 1e-4) << "sample " << i << ": " << measured.transpose() << " vs "
                           << it->second.transpose();
    worst = std::max(worst, error);
    const Eigen::Vector2d noise(noisy_samples[i].left_rad_s - measured.x(),
                                noisy_samples[i].right_rad_s - measured.y());
    sum_sq += noise.squaredNorm();
    ++compared;
    if (error > 1e-4) break;  // one message is enough
  }
  ASSERT_GT(compared, 2000);
  const double sigma = std::sqrt(sum_sq / (2.0 * compared));
  EXPECT_NEAR(sigma, options.wheel.config.noise_rad_s, 0.05 * options.wheel.config.noise_rad_s);
}

TEST_P(WheelGnssTest, GnssFixesMatchTheTrueAntennaPosition) {
  const SimulationOptions options = test::SmallLog(GetParam(), 30.0);
  for (bool noise : {false, true}) {
    const Simulator simulator(noise ? options : options.WithoutNoise());
    const GnssLog gnss = simulator.GenerateGnss();
    const ImuLog imu = simulator.GenerateImu();
    std::map<int64_t, geometry::Pose3d> truth;
    for (const io::TrajectorySample& s : imu.truth) truth[s.t_ns] = s.T_W_I;
    const GeographicLib::LocalCartesian enu(options.gnss.origin_lat_deg,
                                            options.gnss.origin_lon_deg, options.gnss.origin_alt_m);
    const Eigen::Vector3d p_I_A = simulator.true_calibration().p_I_A;
    double chi2 = 0.0;
    int inliers = 0, outliers = 0;
    for (size_t i = 0; i < gnss.fixes.size(); ++i) {
      const sensors::GnssFix& fix = gnss.fixes[i];
      Eigen::Vector3d measured;
      enu.Forward(fix.lat_deg, fix.lon_deg, fix.alt_m, measured.x(), measured.y(), measured.z());
      ASSERT_EQ(truth.count(fix.t_ns), 1u) << "GNSS stamps fall on IMU stamps";
      const Eigen::Vector3d p_W_A = truth[fix.t_ns] * p_I_A;
      const Eigen::Vector3d error = measured - p_W_A;
      const double t = simulator.TimeOf(fix.t_ns);
      for (const auto& outage : gnss.outages_s) {
        EXPECT_FALSE(t >= outage.first && t < outage.second) << "fix inside an outage at " << t;
      }
      if (!noise) {
        ASSERT_LT(error.norm(), 1e-6) << "fix " << i << " at t = " << t;
        continue;
      }
      if (gnss.is_outlier[i]) {
        EXPECT_GT(error.head<2>().norm(), 2.5) << "outliers are multipath jumps of 3-15 m";
        ++outliers;
      } else {
        chi2 += error.cwiseQuotient(fix.std_enu_m).squaredNorm();
        ++inliers;
      }
    }
    if (!noise) {
      // Every epoch outside the outages has a fix.
      size_t expected_fixes = 0;
      const int64_t epochs = static_cast<int64_t>(std::floor(30.0 * options.gnss.config.rate_hz));
      for (int64_t k = 0; k <= epochs; ++k) {
        const double t = simulator.TimeOf(simulator.StampAt(k / options.gnss.config.rate_hz));
        bool in_outage = false;
        for (const auto& outage : gnss.outages_s) {
          in_outage = in_outage || (t >= outage.first && t < outage.second);
        }
        expected_fixes += in_outage ? 0 : 1;
      }
      EXPECT_EQ(gnss.fixes.size(), expected_fixes);
      EXPECT_LT(expected_fixes, static_cast<size_t>(epochs)) << "the log has an outage";
      continue;
    }
    // Normalized squared errors average 3 (three axes) for errors drawn with the reported
    // sigma; ~250 fixes give a 1-sigma spread of about 0.15.
    ASSERT_GT(inliers, 200);
    EXPECT_NEAR(chi2 / inliers, 3.0, 0.6);
    EXPECT_GE(outliers, 1) << "a 30 s log at 10 Hz and 2% outliers has some";
  }
}

TEST_P(WheelGnssTest, SameSeedSameLogOtherSeedOtherLog) {
  const SimulationOptions options = test::SmallLog(GetParam(), 8.0);
  const Simulator a(options), b(options);
  SimulationOptions other_options = options;
  other_options.seed += 1;
  const Simulator other(other_options);
  const ImuLog imu_a = a.GenerateImu(), imu_b = b.GenerateImu(), imu_other = other.GenerateImu();
  ASSERT_EQ(imu_a.samples.size(), imu_b.samples.size());
  for (size_t k = 0; k < imu_a.samples.size(); ++k) {
    ASSERT_EQ(imu_a.samples[k].accel_m_s2, imu_b.samples[k].accel_m_s2) << k;
    ASSERT_EQ(imu_a.samples[k].gyro_rad_s, imu_b.samples[k].gyro_rad_s) << k;
  }
  EXPECT_NE(imu_a.samples[10].gyro_rad_s, imu_other.samples[10].gyro_rad_s);
  const lidar::LidarSweep sa = a.GenerateSweep(3), sb = b.GenerateSweep(3);
  EXPECT_EQ(sa.t_ns, sb.t_ns);
  EXPECT_EQ(sa.cloud.points, sb.cloud.points);
  EXPECT_EQ(sa.cloud.intensity, sb.cloud.intensity);
  EXPECT_EQ(a.GenerateGnss().fixes.back().lat_deg, b.GenerateGnss().fixes.back().lat_deg);
  EXPECT_EQ(a.GenerateWheel().back().left_rad_s, b.GenerateWheel().back().left_rad_s);
  EXPECT_EQ(a.nominal_calibration().p_I_L, b.nominal_calibration().p_I_L);
  EXPECT_NE(a.nominal_calibration().p_I_L, other.nominal_calibration().p_I_L);
}

// The other wheel forms follow from the same truth per sample: rear-wheel speeds
// (v -+ omega b / 2) / s, twist v / k_v and omega b_eff / (k_v b_ctrl); exact without noise,
// with the stated noise otherwise. The dataset carries only the form's file.
TEST(SimulatorTest, WheelFormsFollowTheTruthOfEachSample) {
  SimulationOptions options = test::SmallLog(ScenarioType::kUrban, 10.0);
  options.lidar.enabled = false;
  options.true_calibration.wheel_speed_scale_left = 1.02;
  options.true_calibration.wheel_speed_scale_right = 0.99;
  options.true_calibration.odometry_speed_scale = 0.97;
  options.true_calibration.effective_track_m = 1.9;
  options.wheel.config.controller_track_m = 1.5;
  options.wheel.config.noise_m_s = 0.03;
  options.wheel.config.yaw_rate_noise_rad_s = 0.01;
  const Simulator exact(options.WithoutNoise());
  const WheelLog log = exact.GenerateWheelLog();
  const sensors::WheelSpeedSamples speeds = exact.WheelSpeedsOf(log);
  const sensors::OdometrySamples twist = exact.OdometryOf(log);
  ASSERT_EQ(speeds.size(), log.samples.size());
  ASSERT_EQ(twist.size(), log.samples.size());
  const double b = options.true_calibration.track_width_m;
  for (size_t k = 0; k < log.samples.size(); ++k) {
    const double v = log.speed_m_s[k], w = log.yaw_rate_rad_s[k];
    ASSERT_EQ(speeds[k].t_ns, log.samples[k].t_ns);
    ASSERT_NEAR(speeds[k].left_m_s, (v - 0.5 * w * b) / 1.02, 1e-12);
    ASSERT_NEAR(speeds[k].right_m_s, (v + 0.5 * w * b) / 0.99, 1e-12);
    ASSERT_NEAR(twist[k].speed_m_s, v / 0.97, 1e-12);
    ASSERT_NEAR(twist[k].yaw_rate_rad_s, w * 1.9 / (0.97 * 1.5), 1e-12);
  }
  const Simulator noisy(options);
  const WheelLog noisy_log = noisy.GenerateWheelLog();
  const sensors::WheelSpeedSamples noisy_speeds = noisy.WheelSpeedsOf(noisy_log);
  const sensors::OdometrySamples noisy_twist = noisy.OdometryOf(noisy_log);
  double speed_sq = 0.0, odo_speed_sq = 0.0, yaw_sq = 0.0;
  for (size_t k = 0; k < speeds.size(); ++k) {
    speed_sq += std::pow(noisy_speeds[k].left_m_s - speeds[k].left_m_s, 2);
    odo_speed_sq += std::pow(noisy_twist[k].speed_m_s - twist[k].speed_m_s, 2);
    yaw_sq += std::pow(noisy_twist[k].yaw_rate_rad_s - twist[k].yaw_rate_rad_s, 2);
  }
  const double n = static_cast<double>(speeds.size());
  EXPECT_NEAR(std::sqrt(speed_sq / n), 0.03, 0.003);
  EXPECT_NEAR(std::sqrt(odo_speed_sq / n), 0.03, 0.003);
  EXPECT_NEAR(std::sqrt(yaw_sq / n), 0.01, 0.001);
  // Nominal: scales 1, the effective track the physical one; sensors.yaml names the form.
  const sensors::Calibration& nominal = noisy.nominal_calibration();
  EXPECT_EQ(nominal.odometry_speed_scale, 1.0);
  EXPECT_EQ(nominal.wheel_speed_scale_left, 1.0);
  EXPECT_EQ(nominal.effective_track_m, options.nominal_track_width_m);
  options.wheel.config.form = sensors::WheelForm::kSpeedYawRate;
  EXPECT_EQ(Simulator(options).sensors_config().wheel->form, sensors::WheelForm::kSpeedYawRate);
  options.true_calibration.odometry_speed_scale = 0.0;
  EXPECT_THROW(Simulator{options}, Error);
}

// Correlated receiver errors (GnssSimOptions::error_correlation_time_s): per axis a first-order
// Gauss-Markov process in units of the reported sigma, so the whitened errors keep unit variance
// while neighbouring fixes' correlate by a = exp(-dt / tau). Off, they are independent.
TEST(SimulatorTest, GnssErrorsCorrelateOverTheirCorrelationTime) {
  SimulationOptions options = test::SmallLog(ScenarioType::kSkidSteer, 600.0);
  options.gnss.config.rate_hz = 2.0;
  options.gnss.outlier_probability = 0.0;
  options.gnss.num_outages = 0;
  for (double tau_s : {0.0, 5.0}) {
    options.gnss.error_correlation_time_s = tau_s;
    const Simulator simulator(options);
    const GnssLog gnss = simulator.GenerateGnss();
    const GeographicLib::LocalCartesian enu(options.gnss.origin_lat_deg,
                                            options.gnss.origin_lon_deg, options.gnss.origin_alt_m);
    std::vector<Eigen::Vector3d> unit;
    for (size_t i = 0; i < gnss.fixes.size(); ++i) {
      const sensors::GnssFix& fix = gnss.fixes[i];
      Eigen::Vector3d measured;
      enu.Forward(fix.lat_deg, fix.lon_deg, fix.alt_m, measured.x(), measured.y(), measured.z());
      unit.push_back((measured - gnss.true_p_W_A[i]).cwiseQuotient(fix.std_enu_m));
    }
    ASSERT_GT(unit.size(), 1000u);
    const double expected_lag1 = tau_s > 0.0 ? std::exp(-0.5 / tau_s) : 0.0;
    for (int a = 0; a < 3; ++a) {
      double c0 = 0.0, c1 = 0.0;
      for (size_t i = 0; i < unit.size(); ++i) {
        c0 += unit[i](a) * unit[i](a);
        if (i > 0) c1 += unit[i](a) * unit[i - 1](a);
      }
      const double n = static_cast<double>(unit.size());
      // 1200 fixes: the variance within about 15 %, the lag-1 correlation within 0.07 of a.
      EXPECT_NEAR(c0 / n, 1.0, 0.15 + (tau_s > 0.0 ? 0.35 : 0.0))
          << "tau " << tau_s << ", axis " << a;
      EXPECT_NEAR(c1 / c0, expected_lag1, 0.07) << "tau " << tau_s << ", axis " << a;
    }
  }
  options.gnss.error_correlation_time_s = -1.0;
  EXPECT_THROW(Simulator{options}, Error);
}

TEST(SimulatorTest, NominalCalibrationIsTheTruthPerturbed) {
  for (uint64_t seed = 1; seed <= 5; ++seed) {
    SimulationOptions options = test::SmallLog(ScenarioType::kUrban, 5.0, seed);
    const Simulator simulator(options);
    const sensors::Calibration& t = simulator.true_calibration();
    const sensors::Calibration& n = simulator.nominal_calibration();
    const double rotation_deg = geometry::AngularDistance(t.q_I_L, n.q_I_L) * kRadToDeg;
    // Per-axis sigma 1.5 deg: the angle is a chi(3) draw times 1.5 deg.
    EXPECT_GT(rotation_deg, 0.05) << "seed " << seed;
    EXPECT_LT(rotation_deg, 8.0) << "seed " << seed;
    EXPECT_GT((t.p_I_L - n.p_I_L).norm(), 1e-3) << "seed " << seed;
    EXPECT_LT((t.p_I_L - n.p_I_L).norm(), 0.2) << "seed " << seed;
    EXPECT_NE(t.time_offset_lidar_imu_s, n.time_offset_lidar_imu_s);
    EXPECT_EQ(n.wheel_radius_left_m, options.nominal_wheel_radius_m);
    // The truth is about 1% off the nominal radius, and differs left to right.
    EXPECT_NEAR(t.wheel_radius_left_m / n.wheel_radius_left_m, 1.01, 0.005);
    EXPECT_NE(t.wheel_radius_left_m, t.wheel_radius_right_m);
  }
}

TEST(SimulatorTest, BadOptionsGiveOneClearError) {
  SimulationOptions options;
  options.duration_s = -1.0;
  EXPECT_THROW(Simulator{options}, Error);
  options = SimulationOptions();
  options.lidar.config.num_beams = 0;
  try {
    Simulator simulator(options);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("num_beams"), std::string::npos) << e.what();
  }
  EXPECT_THROW(ParseScenarioType("rural"), Error);
}

// The summary counts the outages the log has: three 20 s outages drawn for a 10 s log overlap
// and run past its end, so they are one outage of the fixes within it.
TEST(SimulatorTest, TheSummaryCountsOutagesWithinTheLog) {
  SimulationOptions options = test::SmallLog(ScenarioType::kUrban, 10.0);
  options.gnss.num_outages = 3;
  options.gnss.outage_duration_s = 20.0;
  const Simulator simulator(options);
  const GnssLog gnss = simulator.GenerateGnss();
  ASSERT_EQ(gnss.outages_s.size(), 3u);
  const SimulationSummary summary =
      Summarize(simulator, simulator.GenerateImu(), sensors::WheelSamples(), gnss, 0, 0);
  EXPECT_EQ(summary.gnss_outages, 1);
  EXPECT_NEAR(summary.gnss_outage_s, 10.0 - gnss.outages_s.front().first, 1e-12);
}

// A refused option names itself, its range and the value given; the sigmas sensors.yaml will
// state must lie in its reader's range (a zero sigma would make a dataset nothing can read).
TEST(SimulatorTest, ARefusedOptionNamesItsRangeAndValue) {
  const auto message = [](const SimulationOptions& options) -> std::string {
    try {
      Simulator simulator(options);
    } catch (const Error& e) {
      return e.what();
    }
    return "no error";
  };
  SimulationOptions options;
  options.wheel.config.noise_rad_s = 0.0;
  EXPECT_THAT(message(options), HasSubstr("wheel noise_rad_s must be in [1e-06, 100] rad/s"));
  EXPECT_THAT(message(options), HasSubstr("got 0"));
  options = SimulationOptions();
  options.wheel.config.yaw_rate_noise_rad_s = -0.1;
  EXPECT_THAT(message(options), HasSubstr("wheel yaw_rate_noise_rad_s must be in"));
  options = SimulationOptions();
  options.wheel.config.lateral_slip_sigma_m_s = 0.0;
  EXPECT_THAT(message(options), HasSubstr("wheel lateral_slip_sigma_m_s must be in"));
  options = SimulationOptions();
  options.wheel.config.cornering_compliance_rad_per_m_s2 = -0.01;
  EXPECT_THAT(message(options),
              HasSubstr("wheel cornering_compliance_rad_per_m_s2 must be in [0, 1] rad/(m/s^2)"));
  options = SimulationOptions();
  options.imu.noise_scale = 0.0;
  EXPECT_THAT(message(options), HasSubstr("imu noise_scale must be > 0"));
  options = SimulationOptions();
  options.imu.stamp_jitter_s = 0.002;  // 0.4 periods at 200 Hz
  EXPECT_THAT(message(options),
              HasSubstr("imu stamp_jitter_s must be in [0, 0.4 / rate_hz) = [0, 0.002) s at "
                        "200 Hz, got 0.002 s"));
  options = SimulationOptions();
  options.gnss.outage_duration_s = -1.0;
  EXPECT_THAT(message(options),
              HasSubstr("gnss outage_duration_s must be finite and >= 0, got -1"));
  options = SimulationOptions();
  options.lidar.config.max_range_m = 0.0;
  EXPECT_THAT(message(options), HasSubstr("0 <= min_range_m < max_range_m, got 1 and 0 m"));
}

INSTANTIATE_TEST_SUITE_P(Scenarios, WheelGnssTest,
                         ::testing::Values(ScenarioType::kUrban, ScenarioType::kHighway,
                                           ScenarioType::kSkidSteer, ScenarioType::kStraight),
                         [](const auto& info) { return test::Name(info.param); });

}  // namespace
}  // namespace sim
}  // namespace autocal
