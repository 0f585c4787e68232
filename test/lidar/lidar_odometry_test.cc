#include "autocal/lidar/lidar_odometry.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>

#include "autocal/common/error.h"
#include "autocal/common/units.h"
#include "lidar/synthetic_scene.h"
#include "support/simulation_cache.h"

namespace autocal {
namespace lidar {
namespace {

using geometry::Pose3d;

// The car drives an arc of 100 m radius along the street, accelerating from 5 to 15 m/s
// over the 2 s sequence, with a slight pitch oscillation; the LiDAR spins at 10 Hz, so each
// sweep is smeared by 0.5 to 1.5 m. Because the speed changes, the smear differs from sweep
// to sweep and does not cancel between consecutive sweeps.
struct ArcTrajectory {
  double initial_speed_m_s = 5.0;
  double acceleration_m_s2 = 5.0;
  double radius_m = 100.0;

  Pose3d T_W_L(double t) const {
    const double arc_m = initial_speed_m_s * t + 0.5 * acceleration_m_s2 * t * t;
    const double yaw = arc_m / radius_m;
    const double pitch_deg = 0.3 * std::sin(2.0 * t);
    return test::MakePose(radius_m * std::sin(yaw) - 40.0, radius_m * (1.0 - std::cos(yaw)), 1.8,
                          yaw * kRadToDeg, pitch_deg, 0.0);
  }
  Eigen::Vector3d AngularVelocityL(double t) const {
    // Body rate of yaw(t) then pitch(t): R^T dR/dt, numerically.
    const double h = 1e-6;
    const Eigen::Quaterniond q0 = T_W_L(t - h).q, q1 = T_W_L(t + h).q;
    return geometry::Log(Eigen::Quaterniond(q0.conjugate() * q1)) / (2 * h);
  }
};

constexpr int kSweeps = 20;
constexpr double kSweepPeriodS = 0.1;

std::vector<LidarSweep> SimulateSequence(const ArcTrajectory& trajectory, uint64_t seed) {
  const test::Scene scene = test::MakeStreetScene(seed, 200.0);
  test::ScanPattern pattern;
  pattern.range_noise_m = 0.02;
  pattern.sweep_period_s = kSweepPeriodS;
  std::mt19937_64 rng(seed);
  std::vector<LidarSweep> sweeps;
  for (int k = 0; k < kSweeps; ++k) {
    const double t_k = k * kSweepPeriodS;
    LidarSweep sweep;
    sweep.t_ns = static_cast<int64_t>(std::llround(t_k * 1e9));
    sweep.cloud = test::SimulateSweep(
        scene, [&](double tau) { return trajectory.T_W_L(t_k + tau); }, pattern, &rng);
    sweeps.push_back(std::move(sweep));
  }
  return sweeps;
}

struct DriftReport {
  double distance_m = 0.0;
  double final_translation_error_m = 0.0;
  double max_relative_rotation_error_deg = 0.0;
  double drift_percent() const { return 100.0 * final_translation_error_m / distance_m; }
};

DriftReport Evaluate(const std::vector<OdometryFrame>& frames, const ArcTrajectory& trajectory) {
  DriftReport report;
  const Pose3d T_W0 = trajectory.T_W_L(0.0);
  for (size_t k = 1; k < frames.size(); ++k) {
    const Pose3d truth_prev = trajectory.T_W_L((k - 1) * kSweepPeriodS);
    const Pose3d truth = trajectory.T_W_L(k * kSweepPeriodS);
    report.distance_m += (truth.p - truth_prev.p).norm();
    const Pose3d relative_truth = truth_prev.Inverse() * truth;
    report.max_relative_rotation_error_deg =
        std::max(report.max_relative_rotation_error_deg,
                 test::RotationErrorDeg(frames[k].T_prev_curr, relative_truth));
  }
  const Pose3d final_truth = T_W0.Inverse() * trajectory.T_W_L((frames.size() - 1) * kSweepPeriodS);
  report.final_translation_error_m = geometry::TranslationError(frames.back().T_W_L, final_truth);
  return report;
}

class LidarOdometryTest : public ::testing::Test {
 protected:
  // Simulated once per test program and build (test/support/simulation_cache.h).
  static void SetUpTestSuite() {
    sweeps_ = new std::vector<LidarSweep>(test::CachedValue<std::vector<LidarSweep>>(
        "arc_sequence_seed_81", [] { return SimulateSequence({}, 81); }));
  }
  static void TearDownTestSuite() { delete sweeps_; }
  static std::vector<LidarSweep>* sweeps_;
};
std::vector<LidarSweep>* LidarOdometryTest::sweeps_ = nullptr;

TEST_F(LidarOdometryTest, TracksTheTrueTrajectoryWithDeskewing) {
  const ArcTrajectory trajectory;
  LidarOdometry odometry;
  for (const LidarSweep& sweep : *sweeps_) odometry.AddSweep(sweep);
  const DriftReport report = Evaluate(odometry.frames(), trajectory);
  RecordProperty("drift_percent", std::to_string(report.drift_percent()));
  RecordProperty("max_relative_rotation_error_deg",
                 std::to_string(report.max_relative_rotation_error_deg));
  EXPECT_LT(report.drift_percent(), 1.0)
      << report.final_translation_error_m << " m over " << report.distance_m << " m";
  EXPECT_LT(report.max_relative_rotation_error_deg, 0.1);
}

TEST_F(LidarOdometryTest, DeskewingRemovesTheMotionDistortionBias) {
  // Without deskewing every sweep is smeared by its own motion: the odometry drifts more and
  // the sweeps fit the map less tightly.
  const ArcTrajectory trajectory;
  LidarOdometryOptions setting;
  setting.deskew = false;
  LidarOdometry skewed(setting);
  for (const LidarSweep& sweep : *sweeps_) skewed.AddSweep(sweep);
  LidarOdometry deskewed;
  for (const LidarSweep& sweep : *sweeps_) deskewed.AddSweep(sweep);
  const DriftReport without = Evaluate(skewed.frames(), trajectory);
  const DriftReport with = Evaluate(deskewed.frames(), trajectory);
  double rmse_without = 0.0, rmse_with = 0.0;
  for (size_t k = 1; k < sweeps_->size(); ++k) {
    rmse_without += skewed.frames()[k].icp.inlier_rmse_m;
    rmse_with += deskewed.frames()[k].icp.inlier_rmse_m;
  }
  RecordProperty("drift_percent_without_deskew", std::to_string(without.drift_percent()));
  RecordProperty("mean_rmse_ratio", std::to_string(rmse_with / rmse_without));
  EXPECT_GT(without.drift_percent(), 2.0 * with.drift_percent())
      << "without deskew " << without.drift_percent() << " %, with " << with.drift_percent()
      << " %";
  EXPECT_LT(rmse_with, rmse_without)
      << "mean inlier RMSE with deskew " << rmse_with / (sweeps_->size() - 1) << " m, without "
      << rmse_without / (sweeps_->size() - 1) << " m";
}

TEST_F(LidarOdometryTest, ImuRotationDeskewsAsWell) {
  const ArcTrajectory trajectory;
  LidarOdometry odometry;
  for (size_t k = 0; k < sweeps_->size(); ++k) {
    // The rate at mid-sweep, as a gyro would give it.
    odometry.AddSweep((*sweeps_)[k], trajectory.AngularVelocityL((k + 0.5) * kSweepPeriodS));
  }
  const DriftReport report = Evaluate(odometry.frames(), trajectory);
  EXPECT_LT(report.drift_percent(), 1.0);
  EXPECT_LT(report.max_relative_rotation_error_deg, 0.1);
}

TEST_F(LidarOdometryTest, CoarseRegistrationGridAndThreadsKeepTracking) {
  const ArcTrajectory trajectory;
  LidarOdometryOptions setting;
  setting.num_threads = 2;
  LidarOdometry threaded(setting);
  setting.num_threads = 1;
  setting.registration_voxel_m = 0.75;
  LidarOdometry coarse(setting);
  LidarOdometry reference;
  for (const LidarSweep& sweep : *sweeps_) {
    threaded.AddSweep(sweep);
    coarse.AddSweep(sweep);
    reference.AddSweep(sweep);
  }
  for (size_t k = 0; k < sweeps_->size(); ++k) {
    // Threads do not change the odometry: the ICP sums its normal equations in fixed blocks of
    // points added in order, the map's k-d tree and normals are those of one thread, and the
    // deskewing is per point. Every pose is the same bit for bit.
    const OdometryFrame& frame = threaded.frames()[k];
    const OdometryFrame& expected = reference.frames()[k];
    EXPECT_EQ(frame.T_W_L.p, expected.T_W_L.p) << "sweep " << k;
    EXPECT_EQ(frame.T_W_L.q.coeffs(), expected.T_W_L.q.coeffs()) << "sweep " << k;
    EXPECT_EQ(frame.T_prev_curr.p, expected.T_prev_curr.p) << "sweep " << k;
    EXPECT_EQ(frame.T_prev_curr.q.coeffs(), expected.T_prev_curr.q.coeffs()) << "sweep " << k;
    EXPECT_EQ(frame.icp.iterations, expected.icp.iterations) << "sweep " << k;
    EXPECT_EQ(frame.icp.covariance, expected.icp.covariance) << "sweep " << k;
    // The coarse grid registers with fewer points (the map keeps them all).
    if (k > 0) {
      EXPECT_LT(coarse.frames()[k].icp.num_correspondences,
                reference.frames()[k].icp.num_correspondences / 2)
          << "sweep " << k;
    }
  }
  const DriftReport report = Evaluate(coarse.frames(), trajectory);
  RecordProperty("coarse_drift_percent", std::to_string(report.drift_percent()));
  EXPECT_LT(report.drift_percent(), 1.0);
  EXPECT_LT(report.max_relative_rotation_error_deg, 0.1);
}

// A NaN time would deskew its point to NaN: the sweep is refused, naming the point, and the
// odometry goes on with the next sweeps as if it had not been given.
TEST_F(LidarOdometryTest, RefusesANonFiniteTimeAndKeepsTracking) {
  LidarSweep bad = (*sweeps_)[0];
  bad.cloud.time_s(17) = std::nan("");
  LidarOdometry odometry;
  try {
    odometry.AddSweep(bad);
    ADD_FAILURE() << "a sweep with a NaN time must be refused";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("point 17 has a non-finite time"), std::string::npos)
        << e.what();
  }
  EXPECT_TRUE(odometry.frames().empty());
  for (int k = 0; k < 4; ++k) EXPECT_NO_THROW(odometry.AddSweep((*sweeps_)[k])) << k;
  EXPECT_EQ(odometry.frames().size(), 4u);
}

// A sweep whose registration fails leaves the odometry as it was: the run goes on exactly as
// one never given that sweep. The bad sweep's point times are 100 s late (a clock fault), so
// deskewing moves its points a kilometre away. On the second sweep there is no velocity yet
// and the first pass registers it; the second pass then fails, after the map's first sweep
// has been deskewed with its velocity. Later the first pass fails, after the map took in the
// previous sweep. A 3-sweep map drops sweeps within the sequence, so a miscounted sweep shows.
TEST_F(LidarOdometryTest, AFailedSweepLeavesTheOdometryAsItWas) {
  LidarOdometryOptions setting;
  setting.local_map_sweeps = 3;
  constexpr size_t kUsed = 12;
  LidarOdometry reference(setting);
  LidarOdometry interrupted(setting);
  int refused = 0;
  for (size_t k = 0; k < kUsed; ++k) {
    const LidarSweep& sweep = (*sweeps_)[k];
    reference.AddSweep(sweep);
    if (k == 1 || k == 6) {
      LidarSweep late = sweep;
      late.t_ns = (*sweeps_)[k - 1].t_ns + 50'000'000;
      late.cloud.time_s.array() += 100.0;
      try {
        interrupted.AddSweep(late);
        ADD_FAILURE() << "the late sweep before sweep " << k << " must fail";
      } catch (const Error& e) {
        ++refused;
        RecordProperty("refused_before_sweep_" + std::to_string(k), e.what());
      }
    }
    interrupted.AddSweep(sweep);
  }
  EXPECT_EQ(refused, 2);
  ASSERT_EQ(interrupted.frames().size(), kUsed);
  for (size_t k = 0; k < kUsed; ++k) {
    const OdometryFrame& frame = interrupted.frames()[k];
    const OdometryFrame& expected = reference.frames()[k];
    EXPECT_EQ(frame.t_ns, expected.t_ns) << "sweep " << k;
    EXPECT_EQ(frame.T_W_L.p, expected.T_W_L.p) << "sweep " << k;
    EXPECT_EQ(frame.T_W_L.q.coeffs(), expected.T_W_L.q.coeffs()) << "sweep " << k;
    EXPECT_EQ(frame.icp.iterations, expected.icp.iterations) << "sweep " << k;
    EXPECT_EQ(frame.icp.covariance, expected.icp.covariance) << "sweep " << k;
  }
}

// In a corridor (ground and two walls, a tunnel) the map says nothing about the motion along
// it. By default each frame reports that direction (the pose solved as usual); with
// IcpDegenerate::kHoldGuess the odometry keeps its motion model's motion there, rather than
// "converging" to an along-track shift with a sigma of millimetres. Driving at 10 m/s from a
// start without velocity, the model has none to give: the odometry stands still along the
// axis, and tracks the 0.5 m/s drift across it.
TEST(LidarOdometryCorridorTest, ReportsOrHoldsTheMotionAlongTheAxis) {
  test::Scene corridor;
  corridor.boxes = {test::Box{Eigen::Vector3d(-500, 5, 0), Eigen::Vector3d(500, 6, 4)},
                    test::Box{Eigen::Vector3d(-500, -6, 0), Eigen::Vector3d(500, -5, 4)}};
  const auto T_W_L = [](double t) { return test::MakePose(10.0 * t, 0.5 * t, 1.8, 0.0, 0.0, 0.0); };
  test::ScanPattern pattern;
  pattern.range_noise_m = 0.02;
  pattern.sweep_period_s = kSweepPeriodS;
  std::mt19937_64 rng(5);
  std::vector<LidarSweep> sweeps;
  for (int k = 0; k < 6; ++k) {
    const double t_k = k * kSweepPeriodS;
    LidarSweep sweep;
    sweep.t_ns = static_cast<int64_t>(std::llround(t_k * 1e9));
    sweep.cloud = test::SimulateSweep(
        corridor, [&](double tau) { return T_W_L(t_k + tau); }, pattern, &rng);
    sweeps.push_back(std::move(sweep));
  }
  for (const IcpDegenerate mode : {IcpDegenerate::kReport, IcpDegenerate::kHoldGuess}) {
    LidarOdometryOptions setting;
    setting.icp.degenerate = mode;
    LidarOdometry odometry(setting);
    for (int k = 0; k < 6; ++k) {
      const OdometryFrame& frame = odometry.AddSweep(sweeps[k]);
      if (k == 0) continue;
      ASSERT_EQ(frame.icp.weak_translations.size(), 1u) << k;
      EXPECT_GT(frame.icp.weak_translations[0].x(), 0.999) << k;
      EXPECT_TRUE(frame.icp.weak_rotation_axes.empty()) << k;
      if (mode == IcpDegenerate::kReport) continue;
      EXPECT_NEAR(frame.T_W_L.p.x(), 0.0, 3e-3) << k;
      EXPECT_NEAR(frame.T_W_L.p.y(), 0.5 * k * kSweepPeriodS, 0.01) << k;
    }
  }
}

TEST(LidarOdometryErrorsTest, RejectsBadSequences) {
  LidarOdometry odometry;
  LidarSweep sweep;
  sweep.t_ns = 100;
  sweep.cloud.points = Eigen::Matrix3Xd::Random(3, 50);
  EXPECT_THROW(odometry.AddSweep(sweep), Error);  // no per-point time while deskewing
  sweep.cloud.time_s = Eigen::VectorXd::Zero(50);
  odometry.AddSweep(sweep);
  EXPECT_THROW(odometry.AddSweep(sweep), Error);  // same stamp again
  LidarOdometryOptions bad;
  bad.voxel_m = 0.0;
  EXPECT_THROW(LidarOdometry{bad}, Error);
}

}  // namespace
}  // namespace lidar
}  // namespace autocal
