#include "autocal/estimation/gnss_inertial_keyframes.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <iostream>
#include <random>
#include <utility>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/units.h"
#include "autocal/geometry/so3.h"
#include "autocal/sim/simulator.h"
#include "estimation/true_keyframe.h"
#include "support/skid_steer_options.h"

namespace autocal {
namespace estimation {
namespace {

struct StateErrors {
  double position_rms_m = 0.0;
  double velocity_max_m_s = 0.0;
  double rotation_max_deg = 0.0;
  double gyro_bias_max_rad_s = 0.0;
};

// Keyframes every 0.2 s of a simulated drive (LiDAR off), given only their times, rebuilt
// from GNSS (with the simulator's multipath outliers and outages), the IMU and the wheels,
// and compared with the truth.
StateErrors RebuildAndCompare(sim::ScenarioType scenario, uint64_t seed, bool true_calibration) {
  sim::SimulationOptions options;
  options.scenario = scenario;
  options.duration_s = 30.0;
  options.seed = seed;
  options.lidar.enabled = false;
  const sim::Simulator simulator(options);
  const sim::SimulatedLog log = sim::Simulate(simulator);
  std::vector<Keyframe> truth;
  for (double t_s = 0.5; t_s < options.duration_s - 0.5; t_s += 0.2) {
    truth.push_back(test::TrueKeyframe(log.imu, simulator.StampAt(t_s)));
  }
  std::vector<Keyframe> keyframes(truth.size());
  for (size_t k = 0; k < truth.size(); ++k) keyframes[k].t_ns = truth[k].t_ns;
  const sim::GnssSimOptions& g = options.gnss;
  const sensors::EnuConverter enu(g.origin_lat_deg, g.origin_lon_deg, g.origin_alt_m);
  GnssInertialKeyframesOptions rebuild;
  rebuild.imu_noise = simulator.sensors_config().imu.noise;
  const GnssInertialKeyframes result = KeyframesFromGnssAndImu(
      &keyframes, log.imu.samples, WheelData::AngularRates(log.wheel), log.gnss.fixes, enu,
      true_calibration ? simulator.true_calibration() : simulator.nominal_calibration(), rebuild);
  StateErrors e;
  double sum_m2 = 0.0;
  for (size_t k = 0; k < truth.size(); ++k) {
    sum_m2 += (keyframes[k].p_W_I - truth[k].p_W_I).squaredNorm();
    e.velocity_max_m_s = std::max(e.velocity_max_m_s, (keyframes[k].v_W_I - truth[k].v_W_I).norm());
    e.rotation_max_deg =
        std::max(e.rotation_max_deg,
                 geometry::AngularDistance(keyframes[k].q_W_I, truth[k].q_W_I) * kRadToDeg);
    e.gyro_bias_max_rad_s =
        std::max(e.gyro_bias_max_rad_s, (keyframes[k].b_g - truth[k].b_g).norm());
  }
  e.position_rms_m = std::sqrt(sum_m2 / static_cast<double>(truth.size()));
  std::cout << result.placement.num_placed << " placed, " << result.placement.num_bridged
            << " bridged, " << result.gnss_factors << " GNSS and " << result.wheel_factors
            << " wheel factors; cost " << result.initial_cost << " -> " << result.final_cost
            << "; errors: position RMS " << e.position_rms_m << " m, velocity max "
            << e.velocity_max_m_s << " m/s, rotation max " << e.rotation_max_deg
            << " deg, gyro bias max " << e.gyro_bias_max_rad_s << " rad/s\n";
  return e;
}

// The case the rebuild exists for: 120 km/h without turns. With the true lever arm and
// vehicle rotation the states follow the truth to the fix noise (measured 3.0 cm RMS, 0.47
// deg at most: on a drive with little acceleration the pitch and the accelerometer bias are
// hard to tell apart). With the nominal ones (the simulator's: 3 cm and 1.5 deg per axis
// off) the lever-arm error moves every position (measured 5.0 cm RMS, 0.56 deg).
TEST(GnssInertialKeyframes, RebuildsAHighwayDrive) {
  const StateErrors exact = RebuildAndCompare(sim::ScenarioType::kHighway, 3, true);
  EXPECT_LT(exact.position_rms_m, 0.05);
  EXPECT_LT(exact.velocity_max_m_s, 0.1);
  EXPECT_LT(exact.rotation_max_deg, 1.0);
  EXPECT_LT(exact.gyro_bias_max_rad_s, 0.001);
  const StateErrors nominal = RebuildAndCompare(sim::ScenarioType::kHighway, 3, false);
  EXPECT_LT(nominal.position_rms_m, 0.1);
  EXPECT_LT(nominal.velocity_max_m_s, 0.1);
  EXPECT_LT(nominal.rotation_max_deg, 1.5);
}

// An urban drive with a still start (no heading until the car moves), GNSS outages and a
// roundabout (measured 2.5 cm RMS, 0.11 deg at most).
TEST(GnssInertialKeyframes, RebuildsAnUrbanDrive) {
  const StateErrors exact = RebuildAndCompare(sim::ScenarioType::kUrban, 7, true);
  EXPECT_LT(exact.position_rms_m, 0.05);
  EXPECT_LT(exact.velocity_max_m_s, 0.1);
  EXPECT_LT(exact.rotation_max_deg, 0.5);
  EXPECT_LT(exact.gyro_bias_max_rad_s, 0.001);
}

// The slow skid steer (up to 1 m/s, IMU 30 Hz, odometry twist 10 Hz, 0.6 m fixes at 2.5 Hz),
// 30 s with keyframes every 0.4 s from the nominal calibration: the odometry's rows (Eq. F26)
// hold the vehicle's x axis along the track, and the first keyframe's covariance covers its
// error (a chi-square of 3 degrees at 99.9 %: 16.3). Without the odometry the start took the
// yaw 19 deg off, and the window trusted it.
TEST(GnssInertialKeyframes, SlowSkidSteerWithOdometryStatesWhatItKnows) {
  sim::SimulationOptions options = test::SkidSteerOdometryOptions(30.0, 3);
  options.wheel.time_offset_wheel_imu_s = 0.0;
  const sim::Simulator simulator(options);
  const sim::ImuLog imu = simulator.GenerateImu();
  const sim::WheelLog wheel = simulator.GenerateWheelLog();
  const sim::GnssLog gnss = simulator.GenerateGnss();
  std::vector<Keyframe> keyframes, truth;
  for (double t_s = 1.0; t_s < options.duration_s - 1.0; t_s += 0.4) {
    truth.push_back(test::TrueKeyframe(imu, simulator.StampAt(t_s)));
    keyframes.emplace_back();
    keyframes.back().t_ns = truth.back().t_ns;
  }
  WheelData odometry;
  odometry.form = sensors::WheelForm::kSpeedYawRate;
  odometry.odometry = simulator.OdometryOf(wheel);
  odometry.controller_track_m = simulator.nominal_calibration().effective_track_m;
  GnssInertialKeyframesOptions start;
  start.imu_noise = simulator.sensors_config().imu.noise;
  start.placement.half_width_s = 5.0;
  start.gnss.max_fix_gap_s = 1.0;
  start.gnss.max_imu_gap_s = 0.1;
  start.wheel.max_wheel_gap_s = 0.25;
  start.wheel.max_imu_gap_s = 0.1;
  start.wheel.factor =
      factors::WheelFactorOptions::FromOdometryNoise(*simulator.sensors_config().wheel);
  start.first_keyframe_covariance = true;
  const sim::GnssSimOptions& g = options.gnss;
  const GnssInertialKeyframes result = KeyframesFromGnssAndImu(
      &keyframes, imu.samples, odometry, gnss.fixes,
      sensors::EnuConverter(g.origin_lat_deg, g.origin_lon_deg, g.origin_alt_m),
      simulator.nominal_calibration(), start);
  EXPECT_GT(result.wheel_factors, static_cast<int>(keyframes.size()) * 9 / 10);
  ASSERT_TRUE(result.first_covariance.has_value());
  const Eigen::Vector3d e =
      geometry::Log(Eigen::Quaterniond(keyframes.front().q_W_I.conjugate() * truth.front().q_W_I));
  const Eigen::Matrix3d rotation = result.first_covariance->topLeftCorner<3, 3>();
  const double z2 = e.dot(rotation.ldlt().solve(e));
  std::cout << "first keyframe: rotation error " << e.transpose() * kRadToDeg << " deg, sigma "
            << rotation.diagonal().cwiseSqrt().transpose() * kRadToDeg << " deg, z^2 " << z2
            << '\n';
  EXPECT_LT(z2, 16.3);
  EXPECT_LT(e.norm() * kRadToDeg, 5.0);
}

// The first keyframe's sigmas (rotation, position, velocity; 9 of its 15) from a 30 s urban
// drive rebuilt with every fix's std divided by `std_divisor`.
struct StartSigmas {
  GnssInertialKeyframes result;
  Eigen::Matrix<double, 9, 1> sigma;
};
StartSigmas UrbanStartSigmas(double std_divisor, bool gnss_noise_from_residuals) {
  sim::SimulationOptions options;
  options.scenario = sim::ScenarioType::kUrban;
  options.duration_s = 30.0;
  options.seed = 7;
  options.lidar.enabled = false;
  const sim::Simulator simulator(options);
  sim::SimulatedLog log = sim::Simulate(simulator);
  for (sensors::GnssFix& fix : log.gnss.fixes) fix.std_enu_m /= std_divisor;
  std::vector<Keyframe> keyframes;
  for (double t_s = 0.5; t_s < options.duration_s - 0.5; t_s += 0.2) {
    keyframes.emplace_back();
    keyframes.back().t_ns = simulator.StampAt(t_s);
  }
  const sim::GnssSimOptions& g = options.gnss;
  GnssInertialKeyframesOptions rebuild;
  rebuild.imu_noise = simulator.sensors_config().imu.noise;
  rebuild.first_keyframe_covariance = true;
  rebuild.gnss_noise_from_residuals = gnss_noise_from_residuals;
  StartSigmas out;
  out.result = KeyframesFromGnssAndImu(
      &keyframes, log.imu.samples, WheelData::AngularRates(log.wheel), log.gnss.fixes,
      sensors::EnuConverter(g.origin_lat_deg, g.origin_lon_deg, g.origin_alt_m),
      simulator.true_calibration(), rebuild);
  EXPECT_TRUE(out.result.first_covariance.has_value());
  if (out.result.first_covariance) {
    out.sigma = out.result.first_covariance->topLeftCorner<9, 9>().diagonal().cwiseSqrt();
  }
  return out;
}

// A receiver that states its std four times too small: the fixes' scatter about the first solve
// says so (Eq. N2), and the states solved again with it give the first keyframe's rotation,
// position and velocity sigmas within 20 % of the fixes' as simulated, never above them
// (measured: scales 3.39 and 3.19, sigmas 0.85-0.99 of those). The scales read low because the
// residuals are fitted: the keyframes' positions follow their own fixes (E r^2 = (1 - h) s^2, h
// about 0.3 here). Taken as stated, the position sigmas are 0.38-0.52 of those, and a window
// started from them would hold its start far too tightly.
TEST(GnssInertialKeyframes, AnOptimisticGnssStdGetsTheScatterTheFixesShow) {
  const StartSigmas stated = UrbanStartSigmas(1.0, true);
  ASSERT_TRUE(stated.result.gnss_noise.has_value());
  EXPECT_TRUE(stated.result.gnss_noise->Scale().IsOne());
  EXPECT_TRUE(stated.result.gnss_std_scale.IsOne());
  const StartSigmas scaled = UrbanStartSigmas(4.0, true);
  const StartSigmas optimistic = UrbanStartSigmas(4.0, false);
  ASSERT_TRUE(scaled.result.gnss_noise.has_value());
  EXPECT_FALSE(optimistic.result.gnss_noise.has_value());
  const GnssNoiseFromResiduals& noise = *scaled.result.gnss_noise;
  const Eigen::Matrix<double, 9, 1> ratio = scaled.sigma.cwiseQuotient(stated.sigma);
  std::cout << "scales " << noise.horizontal.scale << " (" << noise.horizontal.rows << " rows), "
            << noise.vertical.scale << " (" << noise.vertical.rows << " rows); sigma ratio "
            << ratio.transpose() << "; taken as stated "
            << optimistic.sigma.cwiseQuotient(stated.sigma).transpose() << "\n";
  for (const GnssAxisNoise& axis : {noise.horizontal, noise.vertical}) {
    EXPECT_GE(axis.rows, kMinGnssNoiseRows);
    EXPECT_GT(axis.scale, 3.0);
    EXPECT_LT(axis.scale, 4.4);
  }
  EXPECT_TRUE(scaled.result.gnss_std_scale == noise.Scale());
  for (int i = 0; i < 9; ++i) {
    EXPECT_GT(ratio(i), 0.8) << i;
    EXPECT_LT(ratio(i), 1.02) << i;
  }
  for (int i = 3; i < 6; ++i) {  // the position, which the fixes determine
    EXPECT_LT(optimistic.sigma(i), 0.6 * stated.sigma(i)) << i;
  }
}

// A planar drive made to order: the IMU (200 Hz) at the vehicle frame's origin and the antenna
// there too, fixes at 10 Hz with 3 cm of seeded noise, a gyro whose only error is a constant bias
// about the vertical. The car drives at 10 m/s, turning at a rate that follows its speed, and
// stands during each span of `stands` (begin, end in s), slowing down and speeding up over 5 s.
struct SyntheticDrive {
  sensors::ImuSamples imu;
  sensors::GnssFixes fixes;
  std::vector<Keyframe> truth;  // every 0.5 s from 1 s to 1 s before the end
  std::vector<double> times_s;  // theirs, from the start
  sensors::EnuConverter enu{49.0, 8.4, 110.0};
};

double SmoothStep(double x) {
  x = std::clamp(x, 0.0, 1.0);
  return x * x * (3.0 - 2.0 * x);
}

SyntheticDrive MakeSyntheticDrive(double duration_s,
                                  const std::vector<std::pair<double, double>>& stands,
                                  double initial_yaw_rad, double gyro_bias_rad_s) {
  const double cruise_m_s = 10.0, ramp_s = 5.0, step_s = 1e-3;
  const auto speed = [&](double t) {
    double v = cruise_m_s;
    for (const auto& [begin, end] : stands) {
      const double slowing = 1.0 - SmoothStep((t - begin + ramp_s) / ramp_s);
      v = std::min(v, cruise_m_s * (t < end ? slowing : SmoothStep((t - end) / ramp_s)));
    }
    return v;
  };
  const auto yaw_rate = [&](double t, double v) {
    return 0.04 * std::sin(2.0 * M_PI * t / 50.0) * v / cruise_m_s;
  };
  SyntheticDrive d;
  const int64_t start_ns = 1'700'000'000'000'000'000;
  std::mt19937_64 random(21);
  std::normal_distribution<double> noise(0.0, 1.0);
  Eigen::Vector3d p = Eigen::Vector3d::Zero();
  double yaw = initial_yaw_rad;
  for (int64_t i = 0; i <= std::llround(duration_s / step_s); ++i) {
    const double t = static_cast<double>(i) * step_s;
    const double v = speed(t), dv = (speed(t + 1e-4) - speed(t - 1e-4)) / 2e-4;
    const double w = yaw_rate(t, v);
    const int64_t t_ns = start_ns + i * 1'000'000;
    if (i % 5 == 0) {
      sensors::ImuSample sample;
      sample.t_ns = t_ns;
      sample.gyro_rad_s = Eigen::Vector3d(0.0, 0.0, w + gyro_bias_rad_s);
      sample.accel_m_s2 = Eigen::Vector3d(dv, v * w, 9.80665);
      d.imu.push_back(sample);
    }
    if (i % 100 == 0) {
      sensors::GnssFix fix;
      fix.t_ns = t_ns;
      fix.std_enu_m = Eigen::Vector3d(0.03, 0.03, 0.06);
      const Eigen::Vector3d lla = d.enu.ToGeodetic(
          p + Eigen::Vector3d(0.03 * noise(random), 0.03 * noise(random), 0.06 * noise(random)));
      fix.lat_deg = lla.x();
      fix.lon_deg = lla.y();
      fix.alt_m = lla.z();
      d.fixes.push_back(fix);
    }
    if (i % 500 == 0 && t >= 1.0 && t <= duration_s - 1.0) {
      Keyframe kf;
      kf.t_ns = t_ns;
      kf.q_W_I = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ());
      kf.p_W_I = p;
      kf.v_W_I = kf.q_W_I * Eigen::Vector3d(v, 0.0, 0.0);
      d.truth.push_back(kf);
      d.times_s.push_back(t);
    }
    // Midpoint steps of the heading and the position.
    const double yaw_mid = yaw + 0.5 * w * step_s, v_mid = v + 0.5 * dv * step_s;
    p += v_mid * step_s * Eigen::Vector3d(std::cos(yaw_mid), std::sin(yaw_mid), 0.0);
    yaw += yaw_rate(t + 0.5 * step_s, v_mid) * step_s;
  }
  return d;
}

// The yaw error (deg) of each keyframe of a synthetic drive rebuilt without wheels; with
// max_iterations 0 the keyframes keep the states the solve would start from.
std::vector<double> SyntheticYawErrorsDeg(const SyntheticDrive& drive, int max_iterations,
                                          GnssInertialKeyframes* result) {
  std::vector<Keyframe> keyframes(drive.truth.size());
  for (size_t k = 0; k < keyframes.size(); ++k) keyframes[k].t_ns = drive.truth[k].t_ns;
  GnssInertialKeyframesOptions options;
  options.max_iterations = max_iterations;
  options.gnss_noise_from_residuals = max_iterations > 0;
  *result = KeyframesFromGnssAndImu(&keyframes, drive.imu, WheelData(), drive.fixes, drive.enu,
                                    sensors::Calibration(), options);
  std::vector<double> error_deg(keyframes.size());
  for (size_t k = 0; k < keyframes.size(); ++k) {
    error_deg[k] = geometry::AngularDistance(keyframes[k].q_W_I, drive.truth[k].q_W_I) * kRadToDeg;
  }
  return error_deg;
}

// The largest of the errors at keyframes within [begin_s, end_s] (and of the keyframes without a
// heading, when only_unheaded), with their count.
double MaxErrorDeg(const SyntheticDrive& drive, const std::vector<double>& error_deg,
                   const GnssInertialKeyframes& result, double begin_s, double end_s,
                   bool only_unheaded, int* count) {
  double max_deg = 0.0;
  *count = 0;
  for (size_t k = 0; k < error_deg.size(); ++k) {
    if (drive.times_s[k] < begin_s || drive.times_s[k] > end_s) continue;
    if (only_unheaded && result.placement.heading[k]) continue;
    max_deg = std::max(max_deg, error_deg[k]);
    ++*count;
  }
  return max_deg;
}

// Keyframes without a trusted heading start from their gyro yaw anchored to the headings around
// them (Eq. K9b). A 600 s drive whose gyro has a bias of 5e-3 rad/s about the vertical stops for
// 30 s at 500 s, facing west (the yaw near pi, where angles wrap). Turned by the one yaw of the
// whole log's headings, the stopped keyframes started 70 deg off, and the heading gate (Eq. K8)
// kept 159 of the 1138 headings: those within 0.2 rad of the log's mean yaw. Now they start
// 0.08 deg off and every heading is kept.
TEST(GnssInertialKeyframes, AStopLateInALongDriveStartsFromTheHeadingsAroundIt) {
  const SyntheticDrive drive = MakeSyntheticDrive(600.0, {{500.0, 530.0}}, 3.1, 5e-3);
  GnssInertialKeyframes start;
  const std::vector<double> error_deg = SyntheticYawErrorsDeg(drive, 0, &start);
  int stopped = 0, unheaded = 0;
  const double stopped_deg = MaxErrorDeg(drive, error_deg, start, 501.0, 529.0, false, &stopped);
  const double unheaded_deg = MaxErrorDeg(drive, error_deg, start, 0.0, 600.0, true, &unheaded);
  const size_t mid_stop = 1028;  // at 515 s
  ASSERT_NEAR(drive.times_s[mid_stop], 515.0, 1e-9);
  const double stop_yaw_deg =
      geometry::AngularDistance(drive.truth[mid_stop].q_W_I, Eigen::Quaterniond::Identity()) *
      kRadToDeg;
  std::cout << start.placement.num_headings << " headings of " << error_deg.size()
            << " keyframes; start yaw errors: " << stopped << " stopped " << stopped_deg
            << " deg at most, " << unheaded << " without a heading " << unheaded_deg
            << " deg; the stop's yaw is " << stop_yaw_deg << " deg from east\n";
  EXPECT_GT(stop_yaw_deg, 175.0);
  EXPECT_GT(start.placement.num_headings, static_cast<int>(error_deg.size()) * 9 / 10);
  EXPECT_GT(stopped, 50);
  EXPECT_LT(stopped_deg, 1.0);
  EXPECT_LT(unheaded_deg, 1.0);
}

// A drive that stands for its first 30 s: the standing keyframes have headings on one side
// only, and start as far off as the gyro bias turns them over the stand (0.15 rad at 5e-3
// rad/s) plus the anchor's span (measured 9.6 deg); turned by the one yaw of the log's
// headings they started 47 deg off.
TEST(GnssInertialKeyframes, AStandingStartStartsFromTheFirstHeadings) {
  const SyntheticDrive drive = MakeSyntheticDrive(300.0, {{0.0, 30.0}}, 3.1, 5e-3);
  GnssInertialKeyframes start;
  const std::vector<double> error_deg = SyntheticYawErrorsDeg(drive, 0, &start);
  int standing = 0;
  const double standing_deg = MaxErrorDeg(drive, error_deg, start, 0.0, 29.0, false, &standing);
  std::cout << standing << " standing keyframes start " << standing_deg << " deg off at most\n";
  EXPECT_GT(standing, 50);
  EXPECT_LT(standing_deg, (30.0 + 5.0) * 5e-3 * kRadToDeg + 1.0);
}

// A phone-grade gyro, 1.2e-2 rad/s of bias, over the same 600 s drive: its yaw turns by 7 rad.
// Started from it, with one yaw for the whole log, keyframes lay up to 180 deg off and the
// GNSS-inertial solve ended in another minimum, with keyframes turned half around (final cost
// 32873 against 1397); started from the headings around each keyframe it ends within 0.33 deg.
TEST(GnssInertialKeyframes, APhoneGradeGyroBiasDoesNotTurnTheDriveAround) {
  const SyntheticDrive drive = MakeSyntheticDrive(600.0, {{500.0, 530.0}}, -0.566, 1.2e-2);
  GnssInertialKeyframes result;
  const std::vector<double> error_deg = SyntheticYawErrorsDeg(drive, 30, &result);
  const double max_deg = *std::max_element(error_deg.begin(), error_deg.end());
  std::cout << "rotation error " << max_deg << " deg at most; cost " << result.initial_cost
            << " -> " << result.final_cost << '\n';
  EXPECT_LT(max_deg, 1.0);
}

TEST(GnssInertialKeyframes, RefusesWhatItCannotDo) {
  std::vector<Keyframe> one(1);
  const sensors::EnuConverter enu(48.0, 11.0, 500.0);
  EXPECT_THROW(KeyframesFromGnssAndImu(&one, {}, WheelData(), {}, enu, sensors::Calibration()),
               Error);
  std::vector<Keyframe> two(2);
  two[1].t_ns = 1000000000;
  sensors::ImuSamples imu(1);  // one sample at t = 0 does not cover the keyframe at 1 s
  EXPECT_THROW(KeyframesFromGnssAndImu(&two, imu, WheelData(), {}, enu, sensors::Calibration()),
               Error);
}

}  // namespace
}  // namespace estimation
}  // namespace autocal
