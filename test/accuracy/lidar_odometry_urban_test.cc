// LiDAR odometry on a simulated urban drive: deskewed scan-to-map registration must track
// the true LiDAR trajectory (moving cars, range noise, dropouts and all).
#include <gtest/gtest.h>

#include <cmath>
#include <iostream>

#include "autocal/common/time.h"
#include "autocal/common/units.h"
#include "autocal/geometry/se3.h"
#include "autocal/lidar/lidar_odometry.h"
#include "autocal/sim/simulator.h"
#include "support/lidar_drive_options.h"

namespace autocal {
namespace {

TEST(LidarOdometryUrban, TracksTheTrueTrajectory) {
  const sim::SimulationOptions options = test::LidarInertialUrbanOptions(20.0, 11);
  const sim::Simulator simulator(options);
  const sensors::Calibration& calibration = simulator.true_calibration();
  const geometry::Pose3d T_I_L(calibration.q_I_L, calibration.p_I_L);

  lidar::LidarOdometry odometry;
  std::vector<geometry::Pose3d> truth;
  for (int k = 0; k < simulator.num_sweeps(); ++k) {
    const lidar::LidarSweep sweep = simulator.GenerateSweep(k);
    // A point at tau = 0 was measured at IMU time stamp + offset.
    const double t_s =
        simulator.TimeOf(sweep.t_ns + SecondsToNs(calibration.time_offset_lidar_imu_s));
    if (t_s < 0.0 || t_s > options.duration_s) continue;
    truth.push_back(simulator.ImuPoseAt(t_s) * T_I_L);
    odometry.AddSweep(sweep);
  }
  const auto& frames = odometry.frames();
  ASSERT_EQ(frames.size(), truth.size());
  ASSERT_GT(frames.size(), 150u);

  double distance_m = 0.0;
  double worst_relative_rotation_deg = 0.0;
  double worst_relative_translation_m = 0.0;
  for (size_t k = 1; k < frames.size(); ++k) {
    const geometry::Pose3d true_step = truth[k - 1].Inverse() * truth[k];
    const geometry::Pose3d est_step = frames[k - 1].T_W_L.Inverse() * frames[k].T_W_L;
    distance_m += true_step.p.norm();
    worst_relative_rotation_deg = std::max(
        worst_relative_rotation_deg, geometry::RotationErrorRad(true_step, est_step) * kRadToDeg);
    worst_relative_translation_m =
        std::max(worst_relative_translation_m, geometry::TranslationError(true_step, est_step));
  }
  // Drift: the end pose relative to the start, estimated vs true.
  const geometry::Pose3d true_total = truth.front().Inverse() * truth.back();
  const geometry::Pose3d est_total = frames.front().T_W_L.Inverse() * frames.back().T_W_L;
  const double drift_percent =
      100.0 * geometry::TranslationError(true_total, est_total) / distance_m;
  const double heading_drift_deg_per_100m =
      100.0 * geometry::RotationErrorRad(true_total, est_total) * kRadToDeg / distance_m;
  std::cout << frames.size() << " sweeps over " << distance_m << " m: drift " << drift_percent
            << " % of distance, " << heading_drift_deg_per_100m
            << " deg/100 m; worst sweep-to-sweep error " << worst_relative_translation_m * 100.0
            << " cm, " << worst_relative_rotation_deg << " deg\n";
  // Goals of a usable odometry for the calibration's hand-eye initialization, in the usual
  // odometry metrics: drift within 1 % of distance and 1 deg per 100 m, every relative
  // motion within 5 cm and 0.2 deg.
  EXPECT_LT(drift_percent, 1.0);
  EXPECT_LT(heading_drift_deg_per_100m, 1.0);
  EXPECT_LT(worst_relative_translation_m, 0.05);
  EXPECT_LT(worst_relative_rotation_deg, 0.2);
}

}  // namespace
}  // namespace autocal
