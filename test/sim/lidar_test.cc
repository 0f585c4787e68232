// Every simulated LiDAR point, moved into W with the true pose at its true IMU time
// (stamp + tau + time offset) and the true extrinsic, lies on a world surface.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "autocal/common/time.h"
#include "autocal/sim/simulator.h"
#include "sim/sim_test_util.h"

namespace autocal {
namespace sim {
namespace {

class LidarTest : public ::testing::TestWithParam<ScenarioType> {};

// Distances of the sweep's points to the world's surfaces, with the points placed at
// stamp + tau + time_shift_s on the IMU clock (time_shift_s = the true offset is correct).
std::vector<double> SurfaceDistances(const Simulator& simulator, const lidar::LidarSweep& sweep,
                                     double time_shift_s, bool ignore_point_time = false) {
  const sensors::Calibration& truth = simulator.true_calibration();
  const geometry::Pose3d T_I_L(truth.q_I_L, truth.p_I_L);
  std::vector<double> distances;
  distances.reserve(sweep.cloud.size());
  for (int64_t i = 0; i < sweep.cloud.size(); ++i) {
    const double tau = ignore_point_time ? 0.0 : sweep.cloud.time_s(i);
    const double t = simulator.TimeOf(sweep.t_ns) + tau + time_shift_s;
    const Eigen::Vector3d p_W =
        simulator.ImuPoseAt(t) * (T_I_L * Eigen::Vector3d(sweep.cloud.points.col(i)));
    distances.push_back(simulator.scenario().world->DistanceToSurface(p_W, t));
  }
  return distances;
}

double Fraction(const std::vector<double>& values, double above) {
  return static_cast<double>(
             std::count_if(values.begin(), values.end(), [above](double v) { return v > above; })) /
         values.size();
}

std::vector<int> SweepsToCheck(const Simulator& simulator) {
  const int n = simulator.num_sweeps();
  return {0, n / 2, n - 1};
}

TEST_P(LidarTest, NoiseFreePointsLieOnSurfacesAtTheirTrueTime) {
  const Simulator simulator(test::SmallLog(GetParam(), 20.0).WithoutNoise());
  ASSERT_GT(simulator.num_sweeps(), 150);
  const double offset = simulator.true_calibration().time_offset_lidar_imu_s;
  for (int k : SweepsToCheck(simulator)) {
    const lidar::LidarSweep sweep = simulator.GenerateSweep(k);
    ASSERT_GT(sweep.cloud.size(), 3000) << "sweep " << k;
    ASSERT_TRUE(sweep.cloud.has_time());
    EXPECT_GE(sweep.cloud.time_s.minCoeff(), 0.0);
    EXPECT_LT(sweep.cloud.time_s.maxCoeff(), 0.1);
    const std::vector<double> d = SurfaceDistances(simulator, sweep, offset);
    const auto worst = std::max_element(d.begin(), d.end());
    EXPECT_LT(*worst, 1e-6) << "sweep " << k << ", point " << (worst - d.begin()) << " at "
                            << sweep.cloud.points.col(worst - d.begin()).transpose();
  }
}

// A sweep stamped at its end holds the same points at the same instants: the stamp one period
// later, every point's time one period earlier (negative), every noise-free point still on its
// surface at stamp + tau + offset.
TEST_P(LidarTest, AStampAtTheSweepsEndKeepsEveryPointAtItsInstant) {
  SimulationOptions options = test::SmallLog(GetParam(), 20.0).WithoutNoise();
  const Simulator at_start(options);
  options.lidar.stamp_at_end = true;
  const Simulator at_end(options);
  const int64_t period_ns = SecondsToNs(1.0 / options.lidar.config.rate_hz);
  const double offset = at_start.true_calibration().time_offset_lidar_imu_s;
  for (int k : SweepsToCheck(at_start)) {
    const lidar::LidarSweep start = at_start.GenerateSweep(k);
    const lidar::LidarSweep end = at_end.GenerateSweep(k);
    EXPECT_EQ(end.t_ns, start.t_ns + period_ns);
    ASSERT_EQ(end.cloud.size(), start.cloud.size());
    EXPECT_EQ(end.cloud.points, start.cloud.points);
    EXPECT_LT(end.cloud.time_s.maxCoeff(), 0.0);
    EXPECT_LT((end.cloud.time_s.array() + NsToSeconds(period_ns) - start.cloud.time_s.array())
                  .abs()
                  .maxCoeff(),
              1e-12);
    const std::vector<double> d = SurfaceDistances(at_end, end, offset);
    EXPECT_LT(*std::max_element(d.begin(), d.end()), 1e-6) << "sweep " << k;
  }
}

TEST_P(LidarTest, WrongTimeOffsetSignOrIgnoredPointTimeMovesPointsOffSurfaces) {
  // The test above can fail: shifting the time by twice the offset (the sign mistake) or
  // ignoring the per-point time (motion distortion) puts points off their surface. Points on
  // the ground and on walls along the road slide along their surface, so only a few percent
  // (on a highway) move off; with the right time none is off by even 1e-6 m.
  const Simulator simulator(test::SmallLog(GetParam(), 20.0).WithoutNoise());
  const double offset = simulator.true_calibration().time_offset_lidar_imu_s;
  const int k = simulator.num_sweeps() / 2;
  ASSERT_GT(simulator.scenario()
                .trajectory->StateAt(simulator.TimeOf(simulator.SweepStamp(k)))
                .v_W.norm(),
            3.0)
      << "the check needs the car moving";
  const lidar::LidarSweep sweep = simulator.GenerateSweep(k);
  const double wrong_sign = Fraction(SurfaceDistances(simulator, sweep, -offset), 0.05);
  const double no_point_time = Fraction(SurfaceDistances(simulator, sweep, offset, true), 0.05);
  EXPECT_GT(wrong_sign, 0.02) << "fraction of points more than 5 cm off with the wrong sign";
  EXPECT_GT(no_point_time, 0.02) << "fraction more than 5 cm off without per-point time";
}

TEST_P(LidarTest, NoisyPointsLieWithinFewSigmaOfSurfaces) {
  const SimulationOptions options = test::SmallLog(GetParam(), 20.0);
  const Simulator simulator(options);
  const Simulator exact(options.WithoutNoise());
  const double sigma = options.lidar.config.range_noise_m;
  const double offset = simulator.true_calibration().time_offset_lidar_imu_s;
  for (int k : SweepsToCheck(simulator)) {
    const lidar::LidarSweep sweep = simulator.GenerateSweep(k);
    const std::vector<double> d = SurfaceDistances(simulator, sweep, offset);
    EXPECT_LT(*std::max_element(d.begin(), d.end()), 5.0 * sigma) << "sweep " << k;
    // Range noise is along the ray: the range error's spread is sigma; about
    // dropout_probability of the returns are missing.
    const int64_t n_exact = exact.GenerateSweep(k).cloud.size();
    const double kept = static_cast<double>(sweep.cloud.size()) / n_exact;
    EXPECT_NEAR(kept, 1.0 - options.lidar.dropout_probability, 0.01) << "sweep " << k;
    EXPECT_GT(Fraction(d, 0.5 * sigma), 0.2) << "noise is present in sweep " << k;
  }
}

TEST(LidarTest, MovingVehiclesAppearInTheSweeps) {
  // The highway lead vehicle is about 32 m ahead: some returns come from moving boxes, which
  // a calibration has to reject as outliers.
  const Simulator simulator(test::SmallLog(ScenarioType::kHighway, 10.0).WithoutNoise());
  const lidar::LidarSweep sweep = simulator.GenerateSweep(simulator.num_sweeps() / 2);
  const sensors::Calibration& truth = simulator.true_calibration();
  const geometry::Pose3d T_I_L(truth.q_I_L, truth.p_I_L);
  const World& world = *simulator.scenario().world;
  int on_moving = 0;
  for (int64_t i = 0; i < sweep.cloud.size(); ++i) {
    const double t =
        simulator.TimeOf(sweep.t_ns) + sweep.cloud.time_s(i) + truth.time_offset_lidar_imu_s;
    const Eigen::Vector3d p_W =
        simulator.ImuPoseAt(t) * (T_I_L * Eigen::Vector3d(sweep.cloud.points.col(i)));
    for (const MovingBox& box : world.moving_boxes()) {
      const Eigen::Vector3d q = box.pose_W_O(t).Inverse() * p_W;
      if ((q.cwiseAbs() - box.half_extents_m).maxCoeff() < 1e-6) ++on_moving;
    }
  }
  EXPECT_GT(on_moving, 20);
}

INSTANTIATE_TEST_SUITE_P(Scenarios, LidarTest,
                         ::testing::Values(ScenarioType::kUrban, ScenarioType::kHighway,
                                           ScenarioType::kStraight),
                         [](const auto& info) { return test::Name(info.param); });

}  // namespace
}  // namespace sim
}  // namespace autocal
