#include "autocal/estimation/mount_initialization.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <string>

#include "autocal/common/error.h"
#include "autocal/common/time.h"
#include "autocal/common/units.h"
#include "autocal/geometry/so3.h"
#include "estimation/real_vehicle_logs.h"

namespace autocal {
namespace estimation {
namespace {

constexpr double kGravity = 9.80665;

Eigen::Quaterniond Rx(double deg) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(deg * kDegToRad, Eigen::Vector3d::UnitX()));
}
Eigen::Quaterniond Ry(double deg) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(deg * kDegToRad, Eigen::Vector3d::UnitY()));
}
Eigen::Quaterniond Rz(double deg) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(deg * kDegToRad, Eigen::Vector3d::UnitZ()));
}

// 0 before 3 s, rising smoothly to 1 at 7 s: a still start, then driving.
double Ramp(double t) {
  if (t < 3.0) return 0.0;
  if (t > 7.0) return 1.0;
  return 0.5 * (1.0 - std::cos(M_PI * (t - 3.0) / 4.0));
}

// A planar drive on level ground: signed speed and yaw rate of the vehicle frame.
struct Drive {
  double direction = 1.0;  // -1 reverses
  double turn = 1.0;       // 0 drives straight
  double Speed(double t) const {
    return direction * Ramp(t) * (3.0 + 1.5 * std::sin(0.3 * t) + 0.8 * std::sin(0.77 * t));
  }
  double YawRate(double t) const {
    return turn * Ramp(t) * (0.2 * std::sin(0.25 * t) + 0.1 * std::sin(0.6 * t + 1.0));
  }
  double Acceleration(double t) const { return (Speed(t + 1e-5) - Speed(t - 1e-5)) / 2e-5; }
  double YawAcceleration(double t) const { return (YawRate(t + 1e-5) - YawRate(t - 1e-5)) / 2e-5; }
};

struct SimulatedLog {
  sensors::ImuSamples imu;
  ScalarSeries speed_m_s;
};

// The IMU (at the rear axle) at 100 Hz and the wheel speed at 20 Hz, both with jittered
// stamps, noise and an accelerometer bias; wheel stamps lag: t_imu = t_wheel + offset_s.
SimulatedLog Simulate(const Drive& drive, const Eigen::Quaterniond& q_I_V, double offset_s,
                      unsigned seed, const Eigen::Vector3d& p_V_I = Eigen::Vector3d::Zero()) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::uniform_real_distribution<double> jitter(-0.2, 0.2);
  const Eigen::Vector3d accel_bias(0.02, -0.03, 0.01);
  SimulatedLog log;
  for (double t = 0.0; t < 120.0; t += 0.01) {
    const double stamp = t + 0.01 * jitter(rng);
    const double w = drive.YawRate(stamp), w_dot = drive.YawAcceleration(stamp);
    // At the IMU, p_V_I from the axle: plus d(omega)/dt x p and omega x (omega x p).
    const Eigen::Vector3d f_V =
        Eigen::Vector3d(drive.Acceleration(stamp), drive.Speed(stamp) * w, kGravity) +
        Eigen::Vector3d(-w_dot * p_V_I.y() - w * w * p_V_I.x(),
                        w_dot * p_V_I.x() - w * w * p_V_I.y(), 0.0);
    sensors::ImuSample s;
    s.t_ns = SecondsToNs(stamp);
    s.accel_m_s2 =
        q_I_V * f_V + accel_bias + 0.02 * Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng));
    s.gyro_rad_s = q_I_V * Eigen::Vector3d(0, 0, drive.YawRate(stamp)) +
                   0.002 * Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng));
    log.imu.push_back(s);
  }
  for (double t = 0.0; t < 120.0; t += 0.05) {
    const double stamp = t + 0.05 * jitter(rng);
    log.speed_m_s.push_back(
        {SecondsToNs(stamp), drive.Speed(stamp + offset_s) + 0.01 * gauss(rng)});
  }
  return log;
}

double ErrorDeg(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  return geometry::AngularDistance(a, b) * kRadToDeg;
}

struct Mount {
  const char* name;
  Eigen::Quaterniond q_I_V;
};

TEST(InitializeMount, RecoversMountsFromGravityAndMotion) {
  // R_V_I = Rz(-90) Rx(90): the IMU's y axis up, x right, z backward (test1.bag).
  const Eigen::Quaterniond y_up = (Rz(-90) * Rx(90)).conjugate();
  // x forward, y right, z down: R_V_I = Rx(180).
  const Eigen::Quaterniond z_down = Rx(180).conjugate();
  // 30 deg off the y-up mount about a skew axis.
  const Eigen::Quaterniond skew =
      y_up *
      Eigen::Quaterniond(Eigen::AngleAxisd(30 * kDegToRad, Eigen::Vector3d(1, 2, 3).normalized()));
  for (const Mount& mount :
       {Mount{"y up", y_up}, Mount{"z down", z_down}, Mount{"30 deg off", skew}}) {
    SCOPED_TRACE(mount.name);
    const SimulatedLog log = Simulate(Drive{}, mount.q_I_V, -0.3, 11);
    const MountInitialization m = InitializeMount(log.imu, log.speed_m_s, -0.3);
    EXPECT_TRUE(m.ok) << (m.problems.empty() ? "" : m.problems.front());
    EXPECT_TRUE(m.up.source.find("still period") != std::string::npos) << m.up.source;
    EXPECT_LT(ErrorDeg(m.q_I_V, mount.q_I_V), 0.5);
    EXPECT_LT(m.yaw_sigma_deg, 0.5);
    std::cout << mount.name << ": " << ErrorDeg(m.q_I_V, mount.q_I_V) << " deg, yaw sigma "
              << m.yaw_sigma_deg << " deg, r " << m.fit_correlation << "\n";
  }
}

TEST(InitializeMount, TheSpeedSignGivesForwardWhenReversing) {
  const Eigen::Quaterniond q_I_V = Rz(40) * Rx(10);
  Drive reverse;
  reverse.direction = -1.0;
  const SimulatedLog log = Simulate(reverse, q_I_V, 0.0, 12);
  const MountInitialization m = InitializeMount(log.imu, log.speed_m_s, 0.0);
  EXPECT_TRUE(m.ok);
  EXPECT_LT(ErrorDeg(m.q_I_V, q_I_V), 0.5);
}

TEST(InitializeMount, FitsTheLeverArmOfAnImuAwayFromTheAxle) {
  const Eigen::Quaterniond q_I_V = Rz(-70) * Rx(5);
  const Eigen::Vector3d p_V_I(1.5, -0.6, 0.8);
  const SimulatedLog log = Simulate(Drive{}, q_I_V, 0.0, 16, p_V_I);
  const MountInitialization m = InitializeMount(log.imu, log.speed_m_s, 0.0);
  EXPECT_TRUE(m.ok);
  EXPECT_LT(ErrorDeg(m.q_I_V, q_I_V), 0.5);
  EXPECT_LT((m.lever_arm_m - p_V_I.head<2>()).norm(), 0.1) << m.lever_arm_m.transpose();
}

TEST(InitializeMount, AStraightDriveFindsForwardFromTheSpeedAlone) {
  const Eigen::Quaterniond q_I_V = Ry(-20) * Rz(120);
  Drive straight;
  straight.turn = 0.0;
  const SimulatedLog log = Simulate(straight, q_I_V, 0.1, 13);
  const MountInitialization m = InitializeMount(log.imu, log.speed_m_s, 0.1);
  EXPECT_TRUE(m.ok);
  EXPECT_LT(ErrorDeg(m.q_I_V, q_I_V), 0.5);
}

TEST(InitializeMount, AVehicleThatNeverMovesHasNoForwardAxis) {
  const Eigen::Quaterniond q_I_V = Rx(180);
  Drive parked;
  parked.direction = 0.0;
  parked.turn = 0.0;
  const SimulatedLog log = Simulate(parked, q_I_V, 0.0, 14);
  const MountInitialization m = InitializeMount(log.imu, log.speed_m_s, 0.0);
  EXPECT_FALSE(m.ok);
  EXPECT_TRUE(m.up.ok);
  EXPECT_FALSE(m.forward_found);
  ASSERT_FALSE(m.problems.empty());
  EXPECT_NE(m.problems.front().find("barely accelerates"), std::string::npos) << m.problems.front();
  EXPECT_LT((m.up.up_I - q_I_V * Eigen::Vector3d::UnitZ()).norm(), 0.01);
}

// A window that is not positive stepped the horizontal fit by zero nanoseconds forever (or
// backwards), and one past SecondsToNs's range overflowed: each is refused by name.
TEST(InitializeMount, RefusesAWindowThatIsNotAPositiveDuration) {
  const SimulatedLog log = Simulate(Drive{}, Eigen::Quaterniond::Identity(), 0.0, 16);
  for (double window_s : {0.0, -0.5, std::nan(""), std::numeric_limits<double>::infinity(),
                          kMaxMountWindowS + 1.0, 1e300}) {
    MountInitializationOptions options;
    options.window_s = window_s;
    try {
      InitializeMount(log.imu, log.speed_m_s, 0.0, options);
      ADD_FAILURE() << "window " << window_s << " s accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("window_s must lie in (0, 60] s"), std::string::npos)
          << e.what();
    }
  }
  MountInitializationOptions longest;
  longest.window_s = kMaxMountWindowS;
  EXPECT_FALSE(InitializeMount(log.imu, log.speed_m_s, 0.0, longest).forward_found);
}

// The span of the samples averaged, which the accelerometer bias's random walk drifts over
// (pipeline FuseUpAxisIntoMountPrior): the still start when there is one, within the log.
TEST(EstimateUpAxis, ReportsTheSpanAveraged) {
  const SimulatedLog log = Simulate(Drive{}, Eigen::Quaterniond::Identity(), 0.0, 15);
  const UpAxisEstimate up = EstimateUpAxis(log.imu);
  ASSERT_TRUE(up.ok) << up.problem;
  EXPECT_GT(up.span_s, 0.5);
  EXPECT_LE(up.span_s, NsToSeconds(log.imu.back().t_ns - log.imu.front().t_ns));
  EXPECT_NEAR(up.span_s, (up.samples - 1) * NsToSeconds(log.imu[1].t_ns - log.imu[0].t_ns), 0.5)
      << up.source;
}

TEST(EstimateUpAxis, AnAccelerometerInGIsNotGravity) {
  SimulatedLog log = Simulate(Drive{}, Eigen::Quaterniond::Identity(), 0.0, 15);
  for (sensors::ImuSample& s : log.imu) s.accel_m_s2 /= kGravity;
  const UpAxisEstimate up = EstimateUpAxis(log.imu);
  EXPECT_FALSE(up.ok);
  EXPECT_NE(up.problem.find("not gravity"), std::string::npos) << up.problem;
}

// test1.bag: the IMU is mounted with its y axis up. p_V = R_V_I p_I with
// R_V_I = Rz(-90 deg) Rx(+90 deg) (the IMU's x axis points right, z backward), i.e.
// q_I_V = (Rz(-90) Rx(90))^-1. The mean specific force leans 1.3 deg from the IMU's y axis
// and the fit's own standard deviation about the up axis is about 2.8 deg on this rough,
// slow drive (0.11 m/s^2 of modelled horizontal acceleration): the whole rotation came out
// 1.6 deg from the nominal mount, a pass within that noise, not a margin.
// Eq. C4 against its closed form: a prior and gravity's up axis combine per vehicle axis as
// two Gaussians (roll, pitch); the yaw keeps the prior's.
TEST(FuseUpAxis, CombinesRollAndPitchAsTwoGaussiansAndKeepsTheYaw) {
  MountPrior prior;
  prior.q_I_V = Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, -2, 3).normalized()));
  prior.sigma_rad = Eigen::Vector3d(0.08, 0.05, 0.1);
  // The true mount: the prior's centre turned by a small roll and pitch (and a yaw gravity
  // cannot see).
  const Eigen::Vector3d delta_true(0.02, -0.03, 0.04);
  const Eigen::Quaterniond q_true = prior.q_I_V * geometry::Exp(delta_true);
  const Eigen::Vector3d up_I = q_true * Eigen::Vector3d::UnitZ();
  const double up_sigma = 0.03;
  const MountPrior fused = FuseUpAxis(prior, up_I, up_sigma);
  const Eigen::Vector3d delta =
      geometry::Log(Eigen::Quaterniond(prior.q_I_V.conjugate() * fused.q_I_V));
  // The up axis of q_true seen at the prior's centre: (roll, pitch) of delta_true to first order.
  for (int i = 0; i < 2; ++i) {
    const double p2 = prior.sigma_rad(i) * prior.sigma_rad(i);
    const double g2 = up_sigma * up_sigma;
    EXPECT_NEAR(delta(i), p2 / (p2 + g2) * delta_true(i), 2e-3) << i;
    EXPECT_NEAR(fused.sigma_rad(i), std::sqrt(p2 * g2 / (p2 + g2)), 1e-12) << i;
  }
  EXPECT_NEAR(delta(2), 0.0, 1e-3);
  EXPECT_EQ(fused.sigma_rad(2), prior.sigma_rad(2));
  // A precise up axis puts the fused mount's up axis on it; a vague one leaves the prior.
  const MountPrior sharp = FuseUpAxis(prior, up_I, 1e-9);
  EXPECT_LT((sharp.q_I_V * Eigen::Vector3d::UnitZ() - up_I).norm(), 1e-6);
  const MountPrior vague = FuseUpAxis(prior, up_I, 1e6);
  EXPECT_LT(geometry::AngularDistance(vague.q_I_V, prior.q_I_V), 1e-9);
  EXPECT_THROW(FuseUpAxis(prior, up_I, 0.0), Error);
  EXPECT_THROW(FuseUpAxis(prior, Eigen::Vector3d::Zero(), up_sigma), Error);
}

TEST(RealLogs, HuskyMountIsYUp) {
  AUTOCAL_REQUIRE_SHARED_DATA(test::RealBag("test1.bag"));
  const test::VehicleLog log = test::ImportVehicleLog(test::RealBag("test1.bag"));
  const UpAxisEstimate up = EstimateUpAxis(log.imu);
  ASSERT_TRUE(up.ok) << up.problem;
  const WheelImuOffset offset =
      EstimateWheelImuOffset(log.imu, log.speed_m_s, log.yaw_rate_rad_s,
                             Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), up.up_I));
  ASSERT_TRUE(offset.estimate.reliable) << offset.estimate.reason;
  const MountInitialization m = InitializeMount(log.imu, log.speed_m_s, offset.estimate.offset_s);
  const Eigen::Quaterniond R_V_I_expected = Rz(-90) * Rx(90);
  const double error_deg = ErrorDeg(m.q_I_V.conjugate(), R_V_I_expected);
  std::cout << "up from " << m.up.source << "; R_V_I " << error_deg
            << " deg from Rz(-90) Rx(90), yaw sigma " << m.yaw_sigma_deg << " deg, r "
            << m.fit_correlation << ", excitation " << m.excitation_m_s2 << " m/s^2, " << m.windows
            << " windows\n";
  EXPECT_TRUE(m.ok) << m.problems.front();
  EXPECT_LT(error_deg, 2.0);
}

}  // namespace
}  // namespace estimation
}  // namespace autocal
