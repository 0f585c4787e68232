#include "autocal/estimation/clock_offsets.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/time.h"
#include "autocal/sensors/gnss_enu.h"
#include "estimation/real_vehicle_logs.h"

namespace autocal {
namespace estimation {
namespace {

// A smooth signal like a vehicle's yaw rate: a few slow oscillations of different periods.
double Signal(double t_s) {
  return 0.3 * std::sin(0.7 * t_s) + 0.2 * std::sin(1.9 * t_s + 1.0) +
         0.1 * std::sin(4.1 * t_s + 2.0) + 0.05 * std::sin(0.23 * t_s);
}

// Samples at `rate_hz` over [0, duration_s] with stamps jittered by up to +-30 % of the
// interval; the sample stamped t is the signal at reference time t + offset_s, plus noise.
ScalarSeries Sample(double rate_hz, double duration_s, double offset_s, double noise,
                    std::mt19937* rng) {
  std::uniform_real_distribution<double> jitter(-0.3, 0.3);
  std::normal_distribution<double> gauss(0.0, noise);
  ScalarSeries out;
  const double dt_s = 1.0 / rate_hz;
  for (double t = dt_s; t < duration_s; t += dt_s) {
    const double stamp_s = t + jitter(*rng) * dt_s;
    out.push_back({SecondsToNs(stamp_s), Signal(stamp_s + offset_s) + gauss(*rng)});
  }
  return out;
}

struct Rates {
  double reference_hz;
  double sensor_hz;
};

TEST(EstimateSeriesOffset, RecoversKnownOffsetsAtDifferentJitteredRates) {
  std::mt19937 rng(7);
  double worst_fraction = 0.0;  // largest error as a fraction of its tolerance
  for (const Rates rates :
       {Rates{200, 10}, Rates{30, 10}, Rates{50, 50}, Rates{10, 100}, Rates{100, 2.5}}) {
    for (double offset_s = -0.4; offset_s <= 0.401; offset_s += 0.1) {
      const ScalarSeries reference = Sample(rates.reference_hz, 120.0, 0.0, 0.02, &rng);
      const ScalarSeries sensor = Sample(rates.sensor_hz, 120.0, offset_s, 0.02, &rng);
      const SeriesOffsetEstimate e = EstimateSeriesOffset(reference, sensor);
      const double slower_s = 1.0 / std::min(rates.reference_hz, rates.sensor_hz);
      const double tolerance_s = std::max(0.005, 0.05 * slower_s);
      SCOPED_TRACE(std::to_string(rates.reference_hz) + " Hz vs " +
                   std::to_string(rates.sensor_hz) + " Hz, offset " + std::to_string(offset_s));
      EXPECT_TRUE(e.reliable) << e.reason;
      worst_fraction = std::max(worst_fraction, std::abs(e.offset_s - offset_s) / tolerance_s);
      EXPECT_NEAR(e.offset_s, offset_s, tolerance_s);
      EXPECT_GT(e.peak_correlation, 0.95);
    }
  }
  std::cout << "largest error: " << worst_fraction << " of its tolerance\n";
}

TEST(EstimateSeriesOffset, NoiseWithoutSignalIsNotTrusted) {
  std::mt19937 rng(3);
  std::normal_distribution<double> gauss(0.0, 0.1);
  ScalarSeries reference, sensor;
  for (int i = 0; i < 3000; ++i) reference.push_back({SecondsToNs(0.01 * i), gauss(rng)});
  for (int i = 0; i < 300; ++i) sensor.push_back({SecondsToNs(0.1 * i), gauss(rng)});
  const SeriesOffsetEstimate e = EstimateSeriesOffset(reference, sensor);
  EXPECT_FALSE(e.reliable);
  EXPECT_NE(e.reason.find("peak correlation"), std::string::npos) << e.reason;
}

TEST(EstimateSeriesOffset, AFlatSeriesIsTooLittleExcitation) {
  std::mt19937 rng(4);
  const ScalarSeries reference = Sample(100, 60.0, 0.0, 0.001, &rng);
  ScalarSeries sensor = Sample(10, 60.0, 0.2, 0.0, &rng);
  for (TimedValue& s : sensor) s.value *= 0.01;  // 3 mrad/s of yaw rate
  SeriesOffsetOptions options;
  options.min_sensor_std = 0.02;
  const SeriesOffsetEstimate e = EstimateSeriesOffset(reference, sensor, options);
  EXPECT_FALSE(e.reliable);
  EXPECT_NE(e.reason.find("too little variation"), std::string::npos) << e.reason;
}

TEST(EstimateSeriesOffset, AnOffsetBeyondTheRangePeaksAtItsEdge) {
  std::mt19937 rng(5);
  const ScalarSeries reference = Sample(100, 120.0, 0.0, 0.01, &rng);
  const ScalarSeries sensor = Sample(10, 120.0, 1.6, 0.01, &rng);
  const SeriesOffsetEstimate e = EstimateSeriesOffset(reference, sensor);
  EXPECT_FALSE(e.reliable);
  EXPECT_FALSE(e.reason.empty());
}

// The comparison checked that the series overlap for offsets within +-1 s; the fine scan
// around a coarse peak at or next to the edge (two 50 ms steps either side) stays inside that
// range, where the interpolation never extrapolates (a candidate beyond it throws). With the
// sparser series the sensor's and the reference's, so that both signs of the shift are used.
TEST(EstimateSeriesOffset, TheFineScanStaysInsideTheCheckedRange) {
  std::mt19937 rng(8);
  for (const Rates rates : {Rates{100, 10}, Rates{10, 100}}) {
    for (double offset_s : {-1.0, -0.95, 0.95, 1.0}) {
      SCOPED_TRACE(std::to_string(rates.reference_hz) + " Hz vs " +
                   std::to_string(rates.sensor_hz) + " Hz, offset " + std::to_string(offset_s));
      const ScalarSeries reference = Sample(rates.reference_hz, 120.0, 0.0, 0.01, &rng);
      const ScalarSeries sensor = Sample(rates.sensor_hz, 120.0, offset_s, 0.01, &rng);
      SeriesOffsetEstimate e;
      ASSERT_NO_THROW(e = EstimateSeriesOffset(reference, sensor));
      EXPECT_LE(std::abs(e.offset_s), 1.0);
      if (std::abs(offset_s) < 1.0) {
        EXPECT_TRUE(e.reliable) << e.reason;
        EXPECT_NEAR(e.offset_s, offset_s, 0.005);
      } else {  // the peak at the edge: the offset may lie beyond it
        EXPECT_FALSE(e.reliable);
        EXPECT_NE(e.reason.find("edge of the search range"), std::string::npos) << e.reason;
      }
    }
  }
}

TEST(EstimateSeriesOffset, AnOppositeSignIsNamed) {
  std::mt19937 rng(6);
  const ScalarSeries reference = Sample(100, 120.0, 0.0, 0.01, &rng);
  ScalarSeries sensor = Sample(10, 120.0, -0.3, 0.01, &rng);
  for (TimedValue& s : sensor) s.value = -s.value;
  const SeriesOffsetEstimate e = EstimateSeriesOffset(reference, sensor);
  EXPECT_FALSE(e.reliable);
  EXPECT_NE(e.reason.find("anti-correlated"), std::string::npos) << e.reason;
  EXPECT_NE(e.reason.find("-0.300"), std::string::npos) << e.reason;
}

TEST(EstimateSeriesOffset, RefusesUnorderedStamps) {
  ScalarSeries reference{{0, 1.0}, {10, 2.0}, {5, 3.0}};
  EXPECT_THROW(EstimateSeriesOffset(reference, reference), Error);
}

TEST(MovingAverage, IsCentredAndDelaysNothing) {
  ScalarSeries ramp;
  for (int i = 0; i < 100; ++i) ramp.push_back({SecondsToNs(0.01 * i), 0.01 * i});
  const ScalarSeries smooth = MovingAverage(ramp, 0.1);
  for (size_t i = 10; i < 90; ++i) EXPECT_NEAR(smooth[i].value, ramp[i].value, 1e-12);
}

// A straight drive with a varying speed: the IMU (x forward, z up) and the wheel speed, whose
// stamps are late by `lag_s` (t_imu = t_wheel - lag_s).
struct StraightDrive {
  sensors::ImuSamples imu;
  ScalarSeries speed_m_s;
  ScalarSeries yaw_rate_rad_s;
};

double DriveSpeed(double t) {
  return 8.0 + 3.0 * std::sin(0.4 * t) + 1.5 * std::sin(1.1 * t + 0.5);
}
double DriveAcceleration(double t) {
  return 1.2 * std::cos(0.4 * t) + 1.65 * std::cos(1.1 * t + 0.5);
}

StraightDrive SimulateStraightDrive(double lag_s, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  StraightDrive d;
  for (double t = 0.0; t < 90.0; t += 0.01) {
    sensors::ImuSample s;
    s.t_ns = SecondsToNs(t);
    s.accel_m_s2 = Eigen::Vector3d(DriveAcceleration(t), 0.0, 9.81) +
                   0.05 * Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng));
    s.gyro_rad_s = 0.002 * Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng));
    d.imu.push_back(s);
  }
  for (double t = 0.013; t < 90.0; t += 0.02) {
    d.speed_m_s.push_back({SecondsToNs(t + lag_s), DriveSpeed(t) + 0.01 * gauss(rng)});
    d.yaw_rate_rad_s.push_back({SecondsToNs(t + lag_s), 0.001 * gauss(rng)});
  }
  return d;
}

TEST(EstimateWheelImuOffset, OnAStraightDriveComparesTheForwardAcceleration) {
  const StraightDrive d = SimulateStraightDrive(0.25, 21);
  const WheelImuOffset wheel =
      EstimateWheelImuOffset(d.imu, d.speed_m_s, d.yaw_rate_rad_s, Eigen::Quaterniond::Identity());
  EXPECT_EQ(wheel.signal, "forward acceleration");
  EXPECT_TRUE(wheel.estimate.reliable) << wheel.estimate.reason;
  EXPECT_NEAR(wheel.estimate.offset_s, -0.25, 0.005);
  EXPECT_NE(wheel.estimate.reason.find("hardly varies"), std::string::npos);
}

TEST(EstimateGnssImuOffset, AlignsTheTrackSpeedWithTheWheelSpeed) {
  const StraightDrive d = SimulateStraightDrive(0.0, 22);
  // Fixes at 10 Hz along a straight line heading north-east, stamped 0.2 s late, 2 cm noise.
  std::mt19937 rng(23);
  std::normal_distribution<double> gauss(0.0, 0.02);
  const sensors::EnuConverter enu(48.0, 11.0, 500.0);
  sensors::GnssFixes fixes;
  double distance_m = 0.0;
  for (double t = 0.0; t < 90.0; t += 0.1) {
    const Eigen::Vector3d p = Eigen::Vector3d(0.6, 0.8, 0.0) * distance_m +
                              Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng));
    const Eigen::Vector3d geodetic = enu.ToGeodetic(p);
    sensors::GnssFix fix;
    fix.t_ns = SecondsToNs(t + 0.2);
    fix.lat_deg = geodetic.x();
    fix.lon_deg = geodetic.y();
    fix.alt_m = geodetic.z();
    fixes.push_back(fix);
    for (int k = 0; k < 100; ++k) distance_m += 0.001 * DriveSpeed(t + 0.001 * k + 0.0005);
  }
  const SeriesOffsetEstimate gnss = EstimateGnssImuOffset(fixes, d.speed_m_s);
  EXPECT_TRUE(gnss.reliable) << gnss.reason;
  EXPECT_NEAR(gnss.offset_s, -0.2, 0.005);

  // Multipath: every 50th fix 3-15 m off sideways. Each spoils the two track speeds that pair
  // it, a second apart; the running median drops those spikes and the offset stays.
  std::uniform_real_distribution<double> off_m(3.0, 15.0);
  double largest_speed_m_s = 0.0;
  for (const TimedValue& s : GnssHorizontalSpeed(fixes, 1.0)) {
    largest_speed_m_s = std::max(largest_speed_m_s, s.value);
  }
  for (size_t i = 25; i < fixes.size(); i += 50) {
    Eigen::Vector3d p = enu.ToEnu(fixes[i]);
    p += off_m(rng) * Eigen::Vector3d(-0.8, 0.6, 0.0);
    const Eigen::Vector3d geodetic = enu.ToGeodetic(p);
    fixes[i].lat_deg = geodetic.x();
    fixes[i].lon_deg = geodetic.y();
  }
  double largest_with_outliers_m_s = 0.0;
  for (const TimedValue& s : GnssHorizontalSpeed(fixes, 1.0)) {
    largest_with_outliers_m_s = std::max(largest_with_outliers_m_s, s.value);
  }
  EXPECT_LT(largest_with_outliers_m_s, largest_speed_m_s + 0.05) << "a spike survived";
  const SeriesOffsetEstimate with_outliers = EstimateGnssImuOffset(fixes, d.speed_m_s);
  EXPECT_TRUE(with_outliers.reliable) << with_outliers.reason;
  EXPECT_NEAR(with_outliers.offset_s, -0.2, 0.005);
}

// The odometry's yaw rate lags the gyro about the up axis by about 0.38 s (its stamps come
// late), so t_imu = t_wheel + offset with offset about -0.38 s.
// A gyro that reads 0.8 times the wheels' yaw rate (slip), 0.01 rad/m of their speed (unequal
// radii) plus a bias and white noise, the wheels 0.3 s late: the fit recovers the scale, the
// speed term and the bias, and the noise as its robust sigma.
// A speed that reverses now and then: its mean does not mimic the bias.
double Speed(double t_s) { return 1.0 + 3.0 * std::sin(0.31 * t_s); }

TEST(CompareYawRates, RecoversScaleBiasAndNoise) {
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.05);
  const Eigen::Vector3d up_I = Eigen::Vector3d(0.2, -1.0, 0.1).normalized();
  sensors::ImuSamples imu;
  for (double t = 0.0; t <= 60.0; t += 0.01) {
    sensors::ImuSample s;
    s.t_ns = SecondsToNs(t);
    s.gyro_rad_s = up_I * (0.8 * Signal(t) + 0.01 * Speed(t) + 0.01 + noise(rng));
    imu.push_back(s);
  }
  ScalarSeries wheel, speed;  // stamped 0.3 s early on their own clock: t_imu = t_wheel + 0.3
  for (double t = 1.0; t <= 58.0; t += 0.1) {
    wheel.push_back({SecondsToNs(t - 0.3), Signal(t)});
    speed.push_back({SecondsToNs(t - 0.3), Speed(t)});
  }
  const YawRateAgreement a = CompareYawRates(imu, speed, wheel, 0.3, up_I);
  EXPECT_GT(a.samples, 500u);
  EXPECT_NEAR(a.scale, 0.8, 0.01);
  EXPECT_NEAR(a.per_speed_rad_m, 0.01, 0.001);
  EXPECT_NEAR(a.bias_rad_s, 0.01, 0.002);
  // The gyro is averaged over the wheels' 0.1 s (10 samples): 0.05 / sqrt(10).
  EXPECT_NEAR(a.residual_sigma_rad_s, 0.05 / std::sqrt(10.0), 0.004);
  // On the wrong clock the shape no longer matches: far more is left.
  EXPECT_GT(CompareYawRates(imu, speed, wheel, 0.0, up_I).residual_sigma_rad_s,
            3.0 * a.residual_sigma_rad_s);
  // Too little to compare, or a speed that is not the yaw rate's.
  const ScalarSeries five(wheel.begin(), wheel.begin() + 5);
  EXPECT_EQ(CompareYawRates(imu, five, five, 0.3, up_I).samples, 0u);
  EXPECT_EQ(CompareYawRates(imu, five, wheel, 0.3, up_I).samples, 0u);
}

TEST(RealLogs, HuskyOdometryLagsTheGyroBy038Seconds) {
  AUTOCAL_REQUIRE_SHARED_DATA(test::RealBag("test1.bag"));
  const test::VehicleLog log = test::ImportVehicleLog(test::RealBag("test1.bag"));
  Eigen::Vector3d up_I = Eigen::Vector3d::Zero();
  for (const sensors::ImuSample& s : log.imu) up_I += s.accel_m_s2;
  up_I.normalize();
  const Eigen::Quaterniond q_I_V =
      Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), up_I);
  const WheelImuOffset wheel =
      EstimateWheelImuOffset(log.imu, log.speed_m_s, log.yaw_rate_rad_s, q_I_V);
  EXPECT_EQ(wheel.signal, "yaw rate");
  EXPECT_TRUE(wheel.estimate.reliable) << wheel.estimate.reason;
  EXPECT_NEAR(wheel.estimate.offset_s, -0.38, 0.05);
  EXPECT_GT(wheel.estimate.peak_correlation, 0.9);
  std::cout << "wheel-IMU offset " << wheel.estimate.offset_s << " s, r "
            << wheel.estimate.peak_correlation << "\n";
  const SeriesOffsetEstimate gnss =
      EstimateGnssImuOffset(log.gnss, Shifted(log.speed_m_s, wheel.estimate.offset_s));
  std::cout << "GNSS-IMU offset " << gnss.offset_s << " s, r " << gnss.peak_correlation
            << (gnss.reliable ? "" : ", not reliable: " + gnss.reason) << "\n";
}

TEST(RealLogs, JackalOdometryYawRateIsNotTrusted) {
  AUTOCAL_REQUIRE_SHARED_DATA(test::RealBag("test2.bag"));
  const test::VehicleLog log = test::ImportVehicleLog(test::RealBag("test2.bag"));
  Eigen::Vector3d up_I = Eigen::Vector3d::Zero();
  for (const sensors::ImuSample& s : log.imu) up_I += s.accel_m_s2;
  up_I.normalize();
  const Eigen::Quaterniond q_I_V =
      Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), up_I);
  const WheelImuOffset wheel =
      EstimateWheelImuOffset(log.imu, log.speed_m_s, log.yaw_rate_rad_s, q_I_V);
  std::cout << "yaw: " << wheel.yaw_rate.offset_s << " r " << wheel.yaw_rate.peak_correlation << " "
            << wheel.yaw_rate.reason << "\n";
  std::cout << "acc: " << wheel.acceleration.offset_s << " r "
            << wheel.acceleration.peak_correlation << " " << wheel.acceleration.reason << "\n";
  EXPECT_FALSE(wheel.yaw_rate.reliable);
  EXPECT_LT(wheel.yaw_rate.peak_correlation, 0.8);
  EXPECT_FALSE(wheel.estimate.reliable) << wheel.signal << " " << wheel.estimate.offset_s;
}

}  // namespace
}  // namespace estimation
}  // namespace autocal
