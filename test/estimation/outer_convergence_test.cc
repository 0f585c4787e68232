#include "estimation/outer_convergence.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

#include "autocal/common/units.h"

namespace autocal {
namespace estimation {
namespace internal {
namespace {

TEST(OuterConvergence, AStepBelowTheThresholdHasConverged) {
  EXPECT_TRUE(StepConverged(0.9e-3, 0.0, 1e-3));
  EXPECT_TRUE(StepConverged(0.0, 0.0, 1e-3));
  EXPECT_FALSE(StepConverged(1.1e-3, 0.0, 1e-3));  // no step of the same map before it
}

// The 600 s urban log's LiDAR translation, its steps of one map 3.91 mm then 1.26 mm (rate
// 0.32): 0.59 mm to come, below 1 mm; the steps that followed moved it 0.29 mm and less.
TEST(OuterConvergence, AShrinkingStepConvergesWhenWhatIsLeftIsBelow) {
  EXPECT_TRUE(StepConverged(1.2567e-3, 3.9137e-3, 1e-3));
  EXPECT_FALSE(StepConverged(1.5e-3, 2e-3, 1e-3));  // rate 0.75: 4.5 mm to come
  EXPECT_FALSE(StepConverged(2e-3, 2e-3, 1e-3));    // not shrinking
  EXPECT_FALSE(StepConverged(3e-3, 2e-3, 1e-3));    // growing
}

// On a geometric sequence of steps a r^k the rule stops at the first step whose remaining sum
// a r^(k+1) / (1 - r) is below the threshold, for slow and fast rates alike.
TEST(OuterConvergence, StopsAGeometricSequenceWhereItsRestFallsBelow) {
  const double threshold = 1e-3;
  for (const double rate : {0.05, 0.2, 0.5, 0.8, 0.95}) {
    SCOPED_TRACE(rate);
    double previous = 0.0;
    double step = 0.05;
    int k = 0;
    while (!StepConverged(step, previous, threshold)) {
      previous = step;
      step *= rate;
      ASSERT_LT(++k, 1000);
    }
    const double rest = step * rate / (1.0 - rate);
    EXPECT_TRUE(step < threshold || rest < threshold);
    if (k > 1) {  // the step before was not yet enough
      const double rest_before = previous * rate / (1.0 - rate);
      EXPECT_GE(previous, threshold);
      EXPECT_GE(rest_before, threshold * (1.0 - 1e-12));
    }
  }
}

TEST(OuterConvergence, EveryQuantityMustHaveConverged) {
  LidarInertialBatchOptions options;
  const OuterStep previous{0.01, 4e-3, 1e-4};
  const OuterStep small{0.001, 0.5e-3, 5e-6};
  EXPECT_TRUE(OuterLoopConverged(options, small, std::nullopt));
  OuterStep moving = small;
  moving.translation_m = 1.2567e-3;
  EXPECT_FALSE(OuterLoopConverged(options, moving, std::nullopt));
  EXPECT_TRUE(OuterLoopConverged(options, moving, previous));
  moving.rotation_deg = 0.009;  // rate 0.9: 0.081 deg to come
  EXPECT_FALSE(OuterLoopConverged(options, moving, previous));
  moving = small;
  moving.time_offset_s = 2e-5;  // rate 0.2, 5 us to come
  EXPECT_TRUE(OuterLoopConverged(options, moving, previous));
  moving.time_offset_s = 8e-5;  // rate 0.8, 320 us to come
  EXPECT_FALSE(OuterLoopConverged(options, moving, previous));
}

TEST(OuterConvergence, StepBetweenMeasuresTheExtrinsicAndTheOffset) {
  sensors::Calibration before;
  sensors::Calibration after = before;
  after.q_I_L = before.q_I_L *
                Eigen::Quaterniond(Eigen::AngleAxisd(0.01 * kDegToRad, Eigen::Vector3d::UnitY()));
  after.p_I_L += Eigen::Vector3d(3e-3, 0.0, 4e-3);
  after.time_offset_lidar_imu_s -= 2e-5;
  const OuterStep step = StepBetween(before, after);
  EXPECT_NEAR(step.rotation_deg, 0.01, 1e-9);
  EXPECT_NEAR(step.translation_m, 5e-3, 1e-15);
  EXPECT_NEAR(step.time_offset_s, 2e-5, 1e-15);
}

}  // namespace
}  // namespace internal
}  // namespace estimation
}  // namespace autocal
