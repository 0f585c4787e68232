#include "estimation/rotation_search.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "autocal/common/time.h"
#include "autocal/common/units.h"
#include "autocal/estimation/imu_motion_table.h"
#include "autocal/geometry/so3.h"
#include "autocal/sim/simulator.h"
#include "estimation/true_keyframe.h"
#include "sim/sim_test_util.h"
#include "support/simulation_cache.h"

namespace autocal {
namespace estimation {
namespace internal {
namespace {

// A straight highway stretch at 33 m/s (16 beams, seed 4), simulated once for the suite, with
// true keyframe states: what the search sees when the keyframes are right and only the
// rotation is not.
class RotationSearchTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    sim::SimulationOptions options = sim::test::SmallLog(sim::ScenarioType::kHighway, 12.0, 4);
    options.wheel.enabled = false;
    options.gnss.enabled = false;
    simulator_ = new sim::Simulator(options);
    log_ = new sim::SimulatedLog(test::CachedSimulatedLog(*simulator_));
  }
  static void TearDownTestSuite() {
    delete log_;
    delete simulator_;
  }

  // Every `stride`-th sweep after the first second, reduced, with its true keyframe.
  void Keyframes(int stride) {
    const sensors::Calibration& truth = simulator_->true_calibration();
    const LidarInertialBatchOptions batch;
    const int64_t begin_ns = log_->imu.samples.front().t_ns + SecondsToNs(1.0);
    const int64_t end_ns = log_->imu.samples.back().t_ns - SecondsToNs(0.3);
    for (size_t i = 0; i < log_->sweeps.size(); i += static_cast<size_t>(stride)) {
      const lidar::LidarSweep& sweep = log_->sweeps[i];
      const int64_t t_k = KeyframeTime(sweep, truth.time_offset_lidar_imu_s);
      if (t_k < begin_ns || t_k > end_ns) continue;
      sweeps_.push_back(SelectForBatch(sweep, batch.pairing));
      keyframes_.push_back(test::TrueKeyframe(log_->imu, t_k));
    }
    ASSERT_GE(sweeps_.size(), 20u);
  }

  StartingRotationSearch Search(const Eigen::Quaterniond& start, double range_deg,
                                int num_threads = 2) const {
    sensors::Calibration calibration = simulator_->true_calibration();
    calibration.q_I_L = start;
    RotationSearchOptions options;
    options.range_rad = range_deg * kDegToRad;
    options.num_threads = num_threads;
    return SearchStartingRotation(log_->imu.samples, sweeps_, keyframes_, calibration,
                                  Eigen::Vector3d(0.0, 0.0, -9.80665), BatchPairingDefaults(),
                                  options);
  }

  // The truth turned by `deg` (degrees about the IMU's x, y, z axes): on this drive z is up
  // and x forward, so z turns the LiDAR's yaw and y its pitch.
  static Eigen::Quaterniond TurnedTruth(const Eigen::Vector3d& deg) {
    return (geometry::Exp(Eigen::Vector3d(deg * kDegToRad)) * simulator_->true_calibration().q_I_L)
        .normalized();
  }
  static Eigen::Quaterniond YawedTruth(double deg) {
    return TurnedTruth(Eigen::Vector3d(0.0, 0.0, deg));
  }

  static sim::Simulator* simulator_;
  static sim::SimulatedLog* log_;
  std::vector<SelectedSweep> sweeps_;
  std::vector<Keyframe> keyframes_;
};

sim::Simulator* RotationSearchTest::simulator_ = nullptr;
sim::SimulatedLog* RotationSearchTest::log_ = nullptr;

double DegreesBetween(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  return geometry::AngularDistance(a, b) * kRadToDeg;
}

// Keyframes 13 m apart (every fourth sweep): a yaw 4 deg off moves the points of consecutive
// keyframes by 0.9 m and few find a plane; the search lands on the grid point nearest the truth
// (measured 0.29 deg from it, steps of 0.86 deg).
TEST_F(RotationSearchTest, FindsAYawDegreesOffBetweenSparseKeyframes) {
  Keyframes(4);
  const Eigen::Quaterniond& truth = simulator_->true_calibration().q_I_L;
  const StartingRotationSearch search = Search(YawedTruth(4.0), 4.5);
  std::cout << "step " << search.step_deg << " deg, " << search.candidates << " candidates, paired "
            << search.paired_at_start << " -> " << search.paired_at_best << ", found "
            << DegreesBetween(search.q_I_L_start, truth) << " deg from the truth\n";
  ASSERT_TRUE(search.searched);
  EXPECT_GT(search.step_deg, 0.5);  // 0.2 m over about 13 m
  EXPECT_LT(search.step_deg, 1.5);
  EXPECT_GT(search.paired_at_best, 2 * search.paired_at_start);
  EXPECT_LT(DegreesBetween(search.q_I_L_start, truth), 0.5 * search.step_deg);  // the nearest
  EXPECT_EQ(search.q_I_L_given.coeffs(), YawedTruth(4.0).coeffs());

  // The same whatever the thread count.
  const StartingRotationSearch one_thread = Search(YawedTruth(4.0), 4.5, 1);
  EXPECT_EQ(one_thread.q_I_L_start.coeffs(), search.q_I_L_start.coeffs());
  EXPECT_EQ(one_thread.paired_at_best, search.paired_at_best);
}

// The second axis (across the travel direction and up: the pitch here) and both at once: the
// search about the first axis, then the second, then the first again lands on the grid point
// nearest the truth.
TEST_F(RotationSearchTest, FindsAPitchAndAYawTogether) {
  Keyframes(4);
  const Eigen::Quaterniond& truth = simulator_->true_calibration().q_I_L;
  for (const Eigen::Vector3d& turn :
       {Eigen::Vector3d(0.0, 3.0, 0.0), Eigen::Vector3d(0.0, -2.5, 3.0)}) {
    const StartingRotationSearch search = Search(TurnedTruth(turn), 4.5);
    std::cout << "turned " << turn.transpose() << " deg: found "
              << DegreesBetween(search.q_I_L_start, truth) << " deg from the truth, "
              << search.candidates << " candidates\n";
    ASSERT_TRUE(search.searched);
    // Within half a step on each axis of the grid: at most sqrt(2) / 2 steps.
    EXPECT_LT(DegreesBetween(search.q_I_L_start, truth), 0.71 * search.step_deg) << turn;
  }
}

// A right rotation stays: no candidate pairs more points than the truth.
TEST_F(RotationSearchTest, KeepsARightRotation) {
  Keyframes(4);
  const Eigen::Quaterniond& truth = simulator_->true_calibration().q_I_L;
  const StartingRotationSearch search = Search(truth, 4.5);
  ASSERT_TRUE(search.searched);
  EXPECT_EQ(search.q_I_L_start.coeffs(), truth.coeffs());
  EXPECT_EQ(search.paired_at_best, search.paired_at_start);
}

// Keyframes 3.3 m apart: one step (3.5 deg) exceeds a 3 deg range, so nothing is searched and
// the rotation stays as given (the solve's coarse levels reach that far there).
TEST_F(RotationSearchTest, SearchesNothingWhenOneStepExceedsTheRange) {
  Keyframes(1);
  const StartingRotationSearch search = Search(YawedTruth(2.0), 3.0);
  EXPECT_FALSE(search.searched);
  EXPECT_EQ(search.candidates, 0);
  EXPECT_EQ(search.q_I_L_start.coeffs(), YawedTruth(2.0).coeffs());
}

}  // namespace
}  // namespace internal
}  // namespace estimation
}  // namespace autocal
