#include "autocal/estimation/lidar_inertial_batch.h"

#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

#include "autocal/common/time.h"
#include "autocal/geometry/so3.h"
#include "autocal/sim/simulator.h"

namespace autocal {
namespace estimation {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

// The true state at IMU time t_ns, interpolated in the simulator's IMU-rate truth.
Keyframe TrueKeyframe(const sim::ImuLog& log, int64_t t_ns) {
  const auto& truth = log.truth;
  auto it = std::lower_bound(truth.begin(), truth.end(), t_ns,
                             [](const io::TrajectorySample& s, int64_t t) { return s.t_ns < t; });
  const size_t i1 = static_cast<size_t>(it - truth.begin());
  const size_t i0 = i1 == 0 ? 0 : i1 - 1;
  const double s = i1 == i0 ? 0.0
                            : static_cast<double>(t_ns - truth[i0].t_ns) /
                                  static_cast<double>(truth[i1].t_ns - truth[i0].t_ns);
  Keyframe kf;
  kf.t_ns = t_ns;
  kf.q_W_I = truth[i0].T_W_I.q.slerp(s, truth[i1].T_W_I.q);
  kf.p_W_I = (1.0 - s) * truth[i0].T_W_I.p + s * truth[i1].T_W_I.p;
  kf.v_W_I = (1.0 - s) * truth[i0].v_W_I + s * truth[i1].v_W_I;
  kf.b_g = log.gyro_bias[i0];
  kf.b_a = log.accel_bias[i0];
  return kf;
}

// A 10 s urban drive with a 16-beam LiDAR, simulated once for the suite.
class LidarInertialBatchTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    sim::SimulationOptions sim_options;
    sim_options.scenario = sim::ScenarioType::kUrban;
    sim_options.duration_s = 10.0;
    sim_options.seed = 7;
    sim_options.lidar.config.num_beams = 16;
    sim_options.wheel.enabled = false;
    sim_options.gnss.enabled = false;
    simulator_ = new sim::Simulator(sim_options);
    log_ = new sim::SimulatedLog(sim::Simulate(*simulator_));
  }
  static void TearDownTestSuite() {
    delete log_;
    delete simulator_;
  }

  // Sweeps whose keyframe and points lie inside the IMU log, with true keyframe states.
  void Setup(const sensors::Calibration& start, const LidarInertialBatchOptions& options) {
    const int64_t imu_begin = log_->imu.samples.front().t_ns + 50'000'000;
    const int64_t imu_end = log_->imu.samples.back().t_ns - 200'000'000;
    for (const lidar::LidarSweep& sweep : log_->sweeps) {
      const int64_t t_k = KeyframeTime(sweep.t_ns, start.time_offset_lidar_imu_s, options);
      if (t_k < imu_begin || t_k > imu_end) continue;
      sweeps_.push_back(sweep);
      keyframes_.push_back(TrueKeyframe(log_->imu, t_k));
    }
    ASSERT_GT(sweeps_.size(), 80u);
  }

  static sim::Simulator* simulator_;
  static sim::SimulatedLog* log_;
  std::vector<lidar::LidarSweep> sweeps_;
  std::vector<Keyframe> keyframes_;
};

sim::Simulator* LidarInertialBatchTest::simulator_ = nullptr;
sim::SimulatedLog* LidarInertialBatchTest::log_ = nullptr;

// Started at the truth, the solve must not move away from it: no bias in the point model,
// the time-offset model, the map or the IMU coupling.
TEST_F(LidarInertialBatchTest, StaysAtTheTruth) {
  LidarInertialBatchOptions options;
  options.imu_noise = simulator_->sensors_config().imu.noise;
  options.outer_iterations = 4;
  options.coarse_to_fine_steps = 0;  // started at the truth: no coarse phase needed
  const sensors::Calibration& truth = simulator_->true_calibration();
  sensors::Calibration calibration = truth;
  Setup(calibration, options);
  const LidarInertialBatchReport report =
      SolveLidarInertialBatch(log_->imu.samples, sweeps_, &keyframes_, &calibration, options);
  const double rotation_error_deg =
      geometry::AngularDistance(calibration.q_I_L, truth.q_I_L) * kRadToDeg;
  const double translation_error_m = (calibration.p_I_L - truth.p_I_L).norm();
  const double offset_error_s =
      std::abs(calibration.time_offset_lidar_imu_s - truth.time_offset_lidar_imu_s);
  std::cout << "rotation error " << rotation_error_deg << " deg, translation "
            << translation_error_m << " m, offset " << offset_error_s * 1e3 << " ms, "
            << report.associated_points << " points, rms " << report.point_rms_m << " m\n";
  EXPECT_LT(rotation_error_deg, 0.02);
  EXPECT_LT(translation_error_m, 0.005);
  // Known limitation (docs/estimation.md, "Batch LiDAR-inertial solve"): the fixed-map
  // association leaves the time offset weakly anchored; it is reported, not yet asserted to
  // the 0.5 ms goal.
  EXPECT_LT(offset_error_s, 2e-3);
  // 2 cm range noise; planes from noisy neighbours and moving cars (Cauchy-weighted) add some.
  EXPECT_LT(report.point_rms_m, 0.035);
}

}  // namespace
}  // namespace estimation
}  // namespace autocal
