#include "autocal/estimation/calibration_initializer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iostream>
#include <random>
#include <string>

#include "autocal/common/error.h"
#include "autocal/common/time.h"
#include "autocal/common/units.h"
#include "autocal/estimation/imu_motion_table.h"
#include "autocal/estimation/lidar_inertial_batch.h"
#include "autocal/geometry/so3.h"
#include "autocal/sim/simulator.h"
#include "estimation/true_keyframe.h"
#include "support/lidar_drive_options.h"
#include "support/simulation_cache.h"

namespace autocal {
namespace estimation {
namespace {

using test::TrueKeyframe;

// The rotation about z and translation that best map estimated keyframe positions onto the
// true ones (least squares; roll and pitch are not fitted: gravity fixes them).
geometry::Pose3d YawAlignment(const std::vector<Keyframe>& estimate,
                              const std::vector<Keyframe>& truth) {
  Eigen::Vector3d mean_est = Eigen::Vector3d::Zero(), mean_true = Eigen::Vector3d::Zero();
  for (size_t k = 0; k < estimate.size(); ++k) {
    mean_est += estimate[k].p_W_I;
    mean_true += truth[k].p_W_I;
  }
  mean_est /= static_cast<double>(estimate.size());
  mean_true /= static_cast<double>(truth.size());
  double sin_sum = 0.0, cos_sum = 0.0;
  for (size_t k = 0; k < estimate.size(); ++k) {
    const Eigen::Vector3d a = estimate[k].p_W_I - mean_est, b = truth[k].p_W_I - mean_true;
    cos_sum += a.x() * b.x() + a.y() * b.y();
    sin_sum += a.x() * b.y() - a.y() * b.x();
  }
  const Eigen::Quaterniond q(
      Eigen::AngleAxisd(std::atan2(sin_sum, cos_sum), Eigen::Vector3d::UnitZ()));
  return geometry::Pose3d(q, mean_true - q * mean_est);
}

std::string Problems(const CalibrationInitialization& init) {
  std::string text;
  for (const std::string& p : init.problems) text += p + "\n";
  return text;
}

// A 28 s urban drive (1.5 s standstill, a straight acceleration and cruise, a roundabout),
// simulated once per test program and build (test/support/simulation_cache.h); the initializer runs
// once without any guess (p_I_L prior zero) and the tests look at that result.
class CalibrationInitializerUrbanTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    simulator_ = new sim::Simulator(test::LidarInertialUrbanOptions(28.0, 3));
    log_ = new sim::SimulatedLog(test::CachedSimulatedLog(*simulator_));
    const auto start = std::chrono::steady_clock::now();
    init_ = new CalibrationInitialization(
        InitializeLidarImu(log_->imu.samples, log_->sweeps, Options()));
    std::cout << "initializer: "
              << std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count()
              << " s for " << log_->sweeps.size() << " sweeps\n";
  }
  static void TearDownTestSuite() {
    delete init_;
    delete log_;
    delete simulator_;
  }
  static CalibrationInitializerOptions Options() {
    CalibrationInitializerOptions options;
    options.imu_noise = simulator_->sensors_config().imu.noise;
    return options;
  }

  static sim::Simulator* simulator_;
  static sim::SimulatedLog* log_;
  static CalibrationInitialization* init_;
};

sim::Simulator* CalibrationInitializerUrbanTest::simulator_ = nullptr;
sim::SimulatedLog* CalibrationInitializerUrbanTest::log_ = nullptr;
CalibrationInitialization* CalibrationInitializerUrbanTest::init_ = nullptr;

TEST_F(CalibrationInitializerUrbanTest, RecoversCalibrationWithoutAGuess) {
  const CalibrationInitialization& init = *init_;
  ASSERT_TRUE(init.ok) << Problems(init);
  ASSERT_EQ(init.odometry.size(), log_->sweeps.size());
  EXPECT_FALSE(init.still_start_is_low_excitation);
  const sensors::Calibration& truth = simulator_->true_calibration();
  const double rotation_error_deg = geometry::AngularDistance(init.q_I_L, truth.q_I_L) * kRadToDeg;
  const double offset_error_s =
      std::abs(init.time_offset_lidar_imu_s - truth.time_offset_lidar_imu_s);
  const Eigen::Vector3d lever_error_m = (init.p_I_L - truth.p_I_L).cwiseAbs();
  std::cout << "rotation error " << rotation_error_deg << " deg (hand-eye alone "
            << geometry::AngularDistance(init.rotation.q_I_L, truth.q_I_L) * kRadToDeg
            << " deg, singular value ratio " << init.rotation.singular_value_ratio
            << "; vertical correction " << init.inertial.vertical_rotation_rad * kRadToDeg << " +- "
            << init.inertial.vertical_rotation_std_rad * kRadToDeg << " deg)\noffset error "
            << offset_error_s * 1e3 << " ms (correlation " << init.time_offset.peak_correlation
            << ")\nlever arm " << init.p_I_L.transpose() << " vs true " << truth.p_I_L.transpose()
            << ", excited " << init.inertial.excited.transpose() << ", std "
            << init.inertial.lever_arm_std_m.transpose() << " m\naccel bias "
            << init.inertial.accel_bias_m_s2.transpose() << " vs true "
            << log_->imu.accel_bias.front().transpose() << "; position rms "
            << init.inertial.position_rms_m << " m, " << init.inertial.downweighted_positions
            << " intervals down-weighted\n";
  // Planar driving leaves the hand-eye rotation about the vertical to ~2 deg of pitch and
  // roll; the accelerations determine the correction (measured sigma 0.25 deg) and apply it
  // (measured 0.81 deg).
  EXPECT_TRUE(init.inertial.vertical_rotation_determined);
  EXPECT_NE(init.inertial.vertical_rotation_rad, 0.0);
  EXPECT_LT(init.inertial.vertical_rotation_std_rad, Options().max_vertical_rotation_std_rad);
  EXPECT_LT(rotation_error_deg, 1.0);
  EXPECT_LT(offset_error_s, 3e-3);  // measured 0.83 ms
  for (int axis = 0; axis < 3; ++axis) {
    if (init.inertial.excited(axis)) {
      EXPECT_LT(lever_error_m(axis), 0.10) << "axis " << axis;
    } else {
      EXPECT_EQ(init.p_I_L(axis), Options().p_I_L_prior(axis)) << "axis " << axis;
    }
  }
  // Mean of ~1.5 s at rest; the true bias also walks (measured 0.63 mrad/s).
  EXPECT_LT((init.still_start.gyro_bias_rad_s - log_->imu.gyro_bias.front()).norm(), 1e-3);
}

TEST_F(CalibrationInitializerUrbanTest, KeyframesFollowTheTrueTrajectory) {
  const CalibrationInitialization& init = *init_;
  ASSERT_TRUE(init.ok) << Problems(init);
  ASSERT_EQ(init.keyframes.size(), init.keyframe_sweeps.size());
  ASSERT_GT(init.keyframes.size(), 250u);
  // Keyframes against the truth after aligning W by yaw and translation.
  std::vector<Keyframe> true_keyframes;
  for (const Keyframe& kf : init.keyframes)
    true_keyframes.push_back(TrueKeyframe(log_->imu, kf.t_ns));
  const geometry::Pose3d T_true_est = YawAlignment(init.keyframes, true_keyframes);
  double worst_rotation_deg = 0.0, worst_position_m = 0.0, worst_velocity_m_s = 0.0;
  for (size_t k = 0; k < init.keyframes.size(); ++k) {
    const Keyframe& est = init.keyframes[k];
    const Keyframe& tru = true_keyframes[k];
    EXPECT_EQ(est.t_ns, KeyframeTime(log_->sweeps[static_cast<size_t>(init.keyframe_sweeps[k])],
                                     init.time_offset_lidar_imu_s));
    worst_rotation_deg = std::max(
        worst_rotation_deg,
        geometry::AngularDistance(Eigen::Quaterniond(T_true_est.q * est.q_W_I), tru.q_W_I) *
            kRadToDeg);
    worst_position_m = std::max(worst_position_m, (T_true_est * est.p_W_I - tru.p_W_I).norm());
    worst_velocity_m_s =
        std::max(worst_velocity_m_s, (T_true_est.q * est.v_W_I - tru.v_W_I).norm());
    EXPECT_EQ(est.b_g, init.still_start.gyro_bias_rad_s);
    EXPECT_EQ(est.b_a, Eigen::Vector3d::Zero());
  }
  std::cout << "keyframes: worst orientation error " << worst_rotation_deg << " deg, position "
            << worst_position_m << " m, velocity " << worst_velocity_m_s << " m/s\n";
  // Measured 1.03 deg, 1.10 m, 0.22 m/s: the 16-beam odometry slips ~4 m along the straight
  // street while accelerating and its pitch drifts; the IMU bridges part of it
  // (docs/initialization.md, "Accuracy").
  EXPECT_LT(worst_rotation_deg, 1.5);
  EXPECT_LT(worst_position_m, 1.5);
  EXPECT_LT(worst_velocity_m_s, 0.4);
  // W has its origin at the first keyframe and that keyframe's yaw is zero.
  EXPECT_LT(init.keyframes.front().p_W_I.norm(), 1e-9);
  const Eigen::Matrix3d R0 = init.keyframes.front().q_W_I.toRotationMatrix();
  EXPECT_NEAR(std::atan2(R0(1, 0), R0(0, 0)), 0.0, 1e-9);
}

// The only guess the chain takes is the lever-arm prior for unexcited axes: a prior 0.3 m
// off per axis changes the rest only through the acceleration fit, where the held lever arm
// meets the rotation about the vertical (measured 0.14 deg). The odometry takes no guess;
// it is reused.
TEST_F(CalibrationInitializerUrbanTest, ResultDoesNotDependOnTheGuess) {
  ASSERT_TRUE(init_->ok) << Problems(*init_);
  CalibrationInitializerOptions options = Options();
  options.p_I_L_prior = simulator_->true_calibration().p_I_L + Eigen::Vector3d(0.3, -0.3, 0.3);
  const CalibrationInitialization other =
      InitializeLidarImuFromOdometry(log_->imu.samples, log_->sweeps, init_->odometry, options);
  ASSERT_TRUE(other.ok) << Problems(other);
  // Same odometry, same rest period: the offset and the hand-eye rotation are identical.
  EXPECT_EQ(other.time_offset_lidar_imu_s, init_->time_offset_lidar_imu_s);
  EXPECT_EQ(other.rotation.q_I_L.coeffs(), init_->rotation.q_I_L.coeffs());
  const double rotation_difference_deg =
      geometry::AngularDistance(other.q_I_L, init_->q_I_L) * kRadToDeg;
  std::cout << "rotation difference " << rotation_difference_deg << " deg, lever arm "
            << other.p_I_L.transpose() << " vs " << init_->p_I_L.transpose() << "\n";
  EXPECT_LT(rotation_difference_deg, 0.3);
  EXPECT_LT(
      geometry::AngularDistance(other.q_I_L, simulator_->true_calibration().q_I_L) * kRadToDeg,
      1.0);
  EXPECT_EQ(other.inertial.excited, init_->inertial.excited);
  for (int axis = 0; axis < 3; ++axis) {
    if (other.inertial.excited(axis)) {
      EXPECT_NEAR(other.p_I_L(axis), init_->p_I_L(axis), 0.01) << "axis " << axis;
    } else {
      EXPECT_EQ(other.p_I_L(axis), options.p_I_L_prior(axis)) << "axis " << axis;
    }
  }
}

TEST_F(CalibrationInitializerUrbanTest, RejectsOdometryThatDoesNotMatchTheSweeps) {
  std::vector<lidar::OdometryFrame> odometry = init_->odometry;
  odometry.pop_back();
  EXPECT_THROW(InitializeLidarImuFromOdometry(log_->imu.samples, log_->sweeps, odometry), Error);
}

// A steady turn has gyro and accelerometer standard deviations as small as rest; its mean
// rate tells it apart. 2 s at rest, then 10 s turning at 0.3 rad/s.
TEST(DetectStillStart, ASteadyTurnIsNotStill) {
  std::mt19937 rng(21);
  std::normal_distribution<double> noise(0.0, 0.002);
  const Eigen::Vector3d bias(0.002, -0.001, 0.003);
  sensors::ImuSamples imu;
  for (int64_t t_ns = 0; t_ns <= SecondsToNs(12.0); t_ns += 5'000'000) {
    const bool turning = t_ns > SecondsToNs(2.0);
    sensors::ImuSample s;
    s.t_ns = t_ns;
    s.gyro_rad_s = bias + Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    s.accel_m_s2 = Eigen::Vector3d(noise(rng), noise(rng), 9.80665 + noise(rng));
    if (turning) {
      s.gyro_rad_s.z() += 0.3;
      s.accel_m_s2.y() += 1.5;  // centripetal, 5 m/s on a 16.7 m radius
    }
    imu.push_back(s);
  }
  const StillStart still = DetectStillStart(imu);
  ASSERT_TRUE(still.found) << still.reason;
  EXPECT_LE(still.t_end_ns, SecondsToNs(2.0));
  EXPECT_LT((still.gyro_bias_rad_s - bias).norm(), 5e-4);
  // Without the rest, nothing is still.
  const sensors::ImuSamples turn_only(imu.begin() + 450, imu.end());
  EXPECT_FALSE(DetectStillStart(turn_only).found);
}

bool Mentions(const CalibrationInitialization& init, const std::string& word) {
  for (const std::string& p : init.problems) {
    if (p.find(word) != std::string::npos) return true;
  }
  return false;
}

// 8 s of the urban drive: the standstill, then straight ahead. No turn: no hand-eye rotation
// and no time offset.
TEST(CalibrationInitializer, ReportsStraightDrivingAsTooLittleRotation) {
  sim::SimulationOptions sim_options = test::LidarInertialUrbanOptions(8.0, 3);
  const sim::SimulatedLog log = sim::Simulate(sim_options);
  const CalibrationInitialization init = InitializeLidarImu(log.imu.samples, log.sweeps);
  std::cout << Problems(init);
  EXPECT_FALSE(init.ok);
  EXPECT_TRUE(Mentions(init, "too little rotation")) << Problems(init);
  EXPECT_TRUE(init.keyframes.empty());
}

// 1.2 s at rest: the still start is found, nothing else is determined.
TEST(CalibrationInitializer, ReportsAStationaryLog) {
  sim::SimulationOptions sim_options = test::LidarInertialUrbanOptions(1.2, 3);
  const sim::SimulatedLog log = sim::Simulate(sim_options);
  const CalibrationInitialization init = InitializeLidarImu(log.imu.samples, log.sweeps);
  std::cout << Problems(init);
  EXPECT_FALSE(init.ok);
  EXPECT_TRUE(init.still_start.found) << init.still_start.reason;
  EXPECT_TRUE(Mentions(init, "time offset")) << Problems(init);
  EXPECT_TRUE(Mentions(init, "too little rotation")) << Problems(init);
  EXPECT_TRUE(init.keyframes.empty());
}

// A sweep the odometry cannot register (three points: too few correspondences) is named by
// its index among the sweeps given and by its stamp, which also names it in the log when the
// caller passed only every n-th sweep.
TEST(CalibrationInitializer, NamesTheSweepTheOdometryFailedAtByItsStamp) {
  const sim::SimulatedLog log = sim::Simulate(test::LidarInertialUrbanOptions(3.0, 3));
  std::vector<lidar::LidarSweep> sweeps = log.sweeps;
  ASSERT_GT(sweeps.size(), 2u);
  lidar::PointCloud& sparse = sweeps[1].cloud;
  sparse.points.conservativeResize(3, 3);
  sparse.time_s.conservativeResize(3);
  if (sparse.intensity.size() > 0) sparse.intensity.conservativeResize(3);
  const CalibrationInitialization init = InitializeLidarImu(log.imu.samples, sweeps);
  EXPECT_FALSE(init.ok);
  const std::string expected = "LiDAR odometry failed at sweep 1 of " +
                               std::to_string(sweeps.size()) + " (stamp " +
                               std::to_string(sweeps[1].t_ns) + " ns, 0.1 s after the first)";
  EXPECT_TRUE(Mentions(init, expected)) << Problems(init);
}

// A lever arm the drive does not determine is not claimed. In a turn at rate w the lever
// arm's centripetal acceleration w^2 p_I_L, a few hundredths of m/s^2, competes with the
// accelerometer bias that the same rotation turns alike. On 30 s of urban driving (seed 4,
// 32 beams, every third sweep as the online estimation lends them) the fit's x and y are
// decimetres off; when a variance factor below 1 still scaled their sigma down, it reported
// them excited at a few centimetres (measured: x 21.6 cm off at sigma 1.4 cm). An axis counted
// as excited must hold the truth within three of its sigmas. Measured: sigma 7.8 / 8.4 cm, no
// axis excited, the nominal value kept.
TEST(CalibrationInitializer, ClaimsNoLeverArmAxisTheDriveDoesNotDetermine) {
  sim::SimulationOptions sim_options = test::LidarInertialUrbanOptions(30.0, 4);
  sim_options.lidar.config.num_beams = 32;
  const sim::Simulator simulator(sim_options);
  const sim::SimulatedLog log = sim::Simulate(simulator);
  std::vector<lidar::LidarSweep> sweeps;
  for (size_t i = 0; i < log.sweeps.size(); i += 3) sweeps.push_back(log.sweeps[i]);
  CalibrationInitializerOptions options;
  options.imu_noise = simulator.sensors_config().imu.noise;
  options.p_I_L_prior = simulator.nominal_calibration().p_I_L;
  const CalibrationInitialization init = InitializeLidarImu(log.imu.samples, sweeps, options);
  ASSERT_TRUE(init.ok) << Problems(init);
  const Eigen::Vector3d error_m = init.p_I_L - simulator.true_calibration().p_I_L;
  std::cout << "lever arm error " << error_m.transpose() << " m, std "
            << init.inertial.lever_arm_std_m.transpose() << " m, excited "
            << init.inertial.excited.transpose() << "\n";
  for (int axis = 0; axis < 3; ++axis) {
    if (init.inertial.excited(axis)) {
      EXPECT_LT(std::abs(error_m(axis)), 3.0 * init.inertial.lever_arm_std_m(axis))
          << "axis " << axis;
    } else {
      EXPECT_EQ(init.p_I_L(axis), options.p_I_L_prior(axis)) << "axis " << axis;
    }
  }
}

// `count` sweeps 0.1 s apart from `first_s` (ten placeholder points each), with the odometry
// pose that `pose_at(t_s)` gives at each one's stamp.
struct SweepsAndOdometry {
  std::vector<lidar::LidarSweep> sweeps;
  std::vector<lidar::OdometryFrame> odometry;
};
template <typename PoseAt>
SweepsAndOdometry SweepsEvery100Ms(int count, double first_s, const PoseAt& pose_at) {
  SweepsAndOdometry out;
  for (int k = 0; k < count; ++k) {
    lidar::LidarSweep sweep;
    sweep.t_ns = SecondsToNs(first_s) + k * 100'000'000LL;
    sweep.cloud.points = Eigen::Matrix3Xd::Zero(3, 10);
    sweep.cloud.time_s = Eigen::VectorXd::LinSpaced(10, 0.0, 0.099);
    out.sweeps.push_back(sweep);
    lidar::OdometryFrame frame;
    frame.t_ns = sweep.t_ns;
    frame.T_W_L = pose_at(NsToSeconds(sweep.t_ns));
    out.odometry.push_back(frame);
  }
  return out;
}

// A drive at rest for 3 s, then turning about all three axes while moving, with exact IMU
// samples (200 Hz, 0 to 17 s) and odometry poses T_O_L = T_W_I T_I_L from `lidar_start_s` on
// (10 Hz sweeps for 10 s). Pose: R_W_I = Exp(phi), body rate Jr(phi) phi'.
struct RestThenDrive {
  static constexpr double kRestEndS = 3.0;
  static Eigen::Vector3d Phi(double t) {
    const double s = std::max(0.0, t - kRestEndS);
    return Eigen::Vector3d(0.08 * std::sin(0.9 * s), 0.06 * std::sin(1.3 * s),
                           0.5 * std::sin(0.4 * s) + 0.2 * s);
  }
  static Eigen::Vector3d PhiDot(double t) {
    if (t < kRestEndS) return Eigen::Vector3d::Zero();
    const double s = t - kRestEndS;
    return Eigen::Vector3d(0.072 * std::cos(0.9 * s), 0.078 * std::cos(1.3 * s),
                           0.2 * std::cos(0.4 * s) + 0.2);
  }
  static Eigen::Vector3d Position(double t) {
    const double s = std::max(0.0, t - kRestEndS);
    return Eigen::Vector3d(3.0 * (s - std::sin(0.8 * s) / 0.8), 2.0 * (1.0 - std::cos(0.6 * s)),
                           0.3 * std::sin(0.5 * s));
  }
  static Eigen::Vector3d Acceleration(double t) {
    if (t < kRestEndS) return Eigen::Vector3d::Zero();
    const double s = t - kRestEndS;
    return Eigen::Vector3d(2.4 * std::sin(0.8 * s), 0.72 * std::cos(0.6 * s),
                           -0.075 * std::sin(0.5 * s));
  }
  static Eigen::Quaterniond Orientation(double t) { return geometry::Exp(Phi(t)); }

  sensors::ImuSamples imu;
  std::vector<lidar::LidarSweep> sweeps;
  std::vector<lidar::OdometryFrame> odometry;
  geometry::Pose3d T_I_L{geometry::Exp(Eigen::Vector3d(0.02, -0.03, 1.2)),
                         Eigen::Vector3d(0.4, -0.1, 0.3)};

  explicit RestThenDrive(double lidar_start_s) {
    for (int64_t t_ns = 0; t_ns <= SecondsToNs(17.0); t_ns += 5'000'000) {
      const double t = NsToSeconds(t_ns);
      sensors::ImuSample sample;
      sample.t_ns = t_ns;
      sample.gyro_rad_s = geometry::RightJacobian(Phi(t)) * PhiDot(t);
      sample.accel_m_s2 =
          Orientation(t).conjugate() * (Acceleration(t) + Eigen::Vector3d(0.0, 0.0, 9.80665));
      imu.push_back(sample);
    }
    SweepsAndOdometry lidar = SweepsEvery100Ms(100, lidar_start_s, [this](double t) {
      return geometry::Pose3d(Orientation(t), Position(t)) * T_I_L;
    });
    sweeps = std::move(lidar.sweeps);
    odometry = std::move(lidar.odometry);
  }
};

// The IMU's up axis in the IMU frame at each keyframe, estimated against true.
double WorstUpAxisErrorDeg(const CalibrationInitialization& init) {
  double worst_deg = 0.0;
  for (const Keyframe& keyframe : init.keyframes) {
    const Eigen::Vector3d up = keyframe.q_W_I.conjugate() * Eigen::Vector3d::UnitZ();
    const Eigen::Vector3d up_true =
        RestThenDrive::Orientation(NsToSeconds(keyframe.t_ns)).conjugate() *
        Eigen::Vector3d::UnitZ();
    worst_deg = std::max(worst_deg, std::acos(std::min(1.0, up.dot(up_true))) * kRadToDeg);
  }
  return worst_deg;
}

// The IMU starts recording before the LiDAR: the rest ends at 3 s, the first keyframe comes
// at 6 s. Gravity at the rest is carried to the first keyframe by integrating the gyro
// backwards over the 3 s in between, in which the IMU rolled and pitched by 3 deg (the forward
// integration threw "IntegrateGyro: the IMU samples do not cover the requested interval").
// Measured: worst up-axis error 0.023 deg (the odometry poses' interpolation to the sweeps'
// middles), 0.052 deg with the LiDAR from 1 s (the first keyframe inside the rest; the turn's
// abrupt start moves the offset by 2 ms); integrated forwards instead, 4.5 deg.
TEST(CalibrationInitializer, AcceptsALidarThatStartsAfterTheRest) {
  for (double lidar_start_s : {6.0, 1.0}) {
    const RestThenDrive drive(lidar_start_s);
    CalibrationInitializerOptions options;
    options.fallback_time_offset_s = 0.0;
    options.fallback_q_I_L = drive.T_I_L.q;
    options.p_I_L_prior = drive.T_I_L.p;
    const CalibrationInitialization init =
        InitializeLidarImuFromOdometry(drive.imu, drive.sweeps, drive.odometry, options);
    ASSERT_TRUE(init.ok) << Problems(init);
    ASSERT_TRUE(init.still_start.found);
    EXPECT_FALSE(init.still_start_is_low_excitation);
    EXPECT_LE(init.still_start.t_end_ns, SecondsToNs(RestThenDrive::kRestEndS));
    ASSERT_FALSE(init.keyframes.empty());
    EXPECT_GE(init.keyframes.front().t_ns, SecondsToNs(lidar_start_s));
    const double worst_deg = WorstUpAxisErrorDeg(init);
    std::cout << "LiDAR from " << lidar_start_s << " s: worst up-axis error " << worst_deg
              << " deg, q_I_L error "
              << geometry::AngularDistance(init.q_I_L, drive.T_I_L.q) * kRadToDeg << " deg\n";
    EXPECT_LT(worst_deg, 0.1);
  }
}

bool MentionsFallback(const CalibrationInitialization& init, const std::string& words) {
  for (const std::string& f : init.fallbacks) {
    if (f.find(words) != std::string::npos) return true;
  }
  return false;
}

// A drive at constant speed straight ahead (20 m/s for 35 s, odometry with 1 cm and 0.02 deg
// of noise, a noisy IMU that never accelerates, hence a low-excitation period instead of a
// rest): nothing turns, the given rotation and offset stand in, and the horizontal
// accelerations carry no direction. The fit's rotation about the vertical was applied anyway:
// 8.2 deg at a sigma of 135 deg (seeds 2-4: 4.5, -4.5, 19.7 deg), rotating even an exact
// given rotation. Now it is held at zero and said so.
TEST(CalibrationInitializer, AStraightDriveKeepsTheGivenRotationAboutTheVertical) {
  for (unsigned seed : {1u, 2u, 3u, 4u}) {
    std::mt19937 rng(seed);
    std::normal_distribution<double> n(0.0, 1.0);
    const auto gauss = [&]() { return Eigen::Vector3d(n(rng), n(rng), n(rng)); };
    sensors::ImuSamples imu;
    for (int64_t t_ns = 0; t_ns <= SecondsToNs(40.0); t_ns += 5'000'000) {
      sensors::ImuSample sample;
      sample.t_ns = t_ns;
      sample.gyro_rad_s = 0.002 * gauss();
      sample.accel_m_s2 = Eigen::Vector3d(0.0, 0.0, 9.80665) + 0.05 * gauss();
      imu.push_back(sample);
    }
    const SweepsAndOdometry lidar = SweepsEvery100Ms(350, 1.0, [&](double t) {
      return geometry::Pose3d(geometry::Exp(Eigen::Vector3d(0.0003 * gauss())),
                              Eigen::Vector3d(20.0 * t, 0.0, 0.0) + 0.01 * gauss());
    });
    CalibrationInitializerOptions options;
    options.fallback_time_offset_s = 0.0;
    options.fallback_q_I_L = geometry::Exp(Eigen::Vector3d(0.01, -0.02, 1.3));
    const CalibrationInitialization init =
        InitializeLidarImuFromOdometry(imu, lidar.sweeps, lidar.odometry, options);
    ASSERT_TRUE(init.ok) << Problems(init);
    std::cout << "seed " << seed << ": rotation about the vertical sigma "
              << init.inertial.vertical_rotation_std_rad * kRadToDeg << " deg\n";
    EXPECT_TRUE(init.still_start_is_low_excitation);
    EXPECT_FALSE(init.inertial.vertical_rotation_determined);
    EXPECT_GT(init.inertial.vertical_rotation_std_rad, options.max_vertical_rotation_std_rad);
    EXPECT_EQ(init.inertial.vertical_rotation_rad, 0.0);
    EXPECT_EQ(init.q_I_L.coeffs(), options.fallback_q_I_L->coeffs());
    EXPECT_TRUE(
        MentionsFallback(init, "do not determine the LiDAR-IMU rotation about the vertical"))
        << init.fallbacks.size() << " fallbacks";
  }
}

// Turning on the spot, the IMU level and at the LiDAR's origin, with exact samples: without
// horizontal acceleration the column of the rotation about the vertical is zero, and the fit
// threw "inertial alignment: singular normal equations". Its weak prior keeps the system
// regular, the sigma is the prior's, and the given rotation is kept.
TEST(CalibrationInitializer, NoHorizontalAccelerationLeavesTheVerticalRotationUndetermined) {
  const auto angle = [](double t) {
    const double s = std::max(0.0, t - 3.0);
    return (0.3 / 0.7) * (1.0 - std::cos(0.7 * s)) + (0.2 / 1.9) * (1.0 - std::cos(1.9 * s));
  };
  const auto rate = [](double t) {
    const double s = std::max(0.0, t - 3.0);
    return t < 3.0 ? 0.0 : 0.3 * std::sin(0.7 * s) + 0.2 * std::sin(1.9 * s);
  };
  sensors::ImuSamples imu;
  for (int64_t t_ns = 0; t_ns <= SecondsToNs(25.0); t_ns += 5'000'000) {
    sensors::ImuSample sample;
    sample.t_ns = t_ns;
    sample.gyro_rad_s = Eigen::Vector3d(0.0, 0.0, rate(NsToSeconds(t_ns)));
    sample.accel_m_s2 = Eigen::Vector3d(0.0, 0.0, 9.80665);
    imu.push_back(sample);
  }
  const SweepsAndOdometry lidar = SweepsEvery100Ms(100, 6.0, [&](double t) {
    return geometry::Pose3d(
        Eigen::Quaterniond(Eigen::AngleAxisd(angle(t), Eigen::Vector3d::UnitZ())),
        Eigen::Vector3d::Zero());
  });
  CalibrationInitializerOptions options;
  options.fallback_time_offset_s = 0.0;
  options.fallback_q_I_L = Eigen::Quaterniond::Identity();
  const CalibrationInitialization init =
      InitializeLidarImuFromOdometry(imu, lidar.sweeps, lidar.odometry, options);
  ASSERT_TRUE(init.ok) << Problems(init);
  EXPECT_FALSE(init.inertial.vertical_rotation_determined);
  EXPECT_NEAR(init.inertial.vertical_rotation_std_rad, options.vertical_rotation_prior_sigma_rad,
              1e-6);
  EXPECT_EQ(init.q_I_L.coeffs(), Eigen::Quaterniond::Identity().coeffs());
  EXPECT_TRUE(MentionsFallback(init, "rotation about the vertical"));
}

}  // namespace
}  // namespace estimation
}  // namespace autocal
