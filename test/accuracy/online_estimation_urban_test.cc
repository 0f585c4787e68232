// The online estimator's accuracy suite (issue goals in docs/sliding_window.md, "Figures"):
// simulated urban logs (seed 1, default sensors) of 60 s and 120 s streamed through the
// sliding window from the simulator's nominal guess with the shipped problems/urban_full.yaml,
// compared with the simulator's truth.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <iostream>
#include <string>

#include "autocal/evaluation/calibration_errors.h"
#include "autocal/evaluation/trajectory_errors.h"
#include "autocal/io/dataset.h"
#include "autocal/io/problem_yaml.h"
#include "autocal/pipeline/online_estimation.h"
#include "autocal/sim/simulator.h"
#include "pipeline/simulated_urban_dataset.h"

namespace autocal {
namespace {

// One drive streamed through the window, with its errors against the truth (printed).
struct UrbanRun {
  explicit UrbanRun(double duration_s) {
    sim::SimulationOptions sim_options;
    sim_options.scenario = sim::ScenarioType::kUrban;
    sim_options.duration_s = duration_s;
    sim_options.seed = 1;
    // Simulated once per run: a cached copy of these long drives would only take disk space.
    const test::SimulatedUrbanDataset data(
        sim_options, "online_urban_" + std::to_string(static_cast<int>(duration_s)) + "s",
        test::DatasetStorage::kPrivate);
    const io::Dataset dataset = io::ReadDataset(data.directory);
    const io::Problem problem = io::ReadProblemYaml(
        (std::filesystem::path(AUTOCAL_SOURCE_DIR) / "problems" / "urban_full.yaml").string());
    result = pipeline::EstimateDatasetOnline(dataset, problem);
    c = evaluation::CompareCalibration(result.calibration.value, data.simulator.true_calibration());
    t = evaluation::CompareTrajectory(result.trajectory, dataset.groundtruth_trajectory);
    smoothed =
        evaluation::CompareTrajectory(result.smoothed_trajectory, dataset.groundtruth_trajectory);
    sigma_p_I_L_mm = 1e3 * result.calibration.uncertainty.T_I_L.sigma_p_m.value_or(
                               Eigen::Vector3d::Constant(std::nan("")));
    std::cout << result.trajectory.size() << " keyframes in " << result.seconds_total
              << " s; T_I_L " << c.T_I_L.rotation_deg.transpose() << " deg, "
              << c.T_I_L.translation_mm.transpose() << " mm (sigma " << sigma_p_I_L_mm.transpose()
              << " mm); offset " << c.time_offset_ms << " ms; radii " << c.wheel_radius_left_percent
              << " / " << c.wheel_radius_right_percent << " %; lever arm " << c.p_I_A_mm.transpose()
              << " mm; T_I_V " << c.T_I_V.rotation_deg.transpose() << " deg; ATE "
              << t.ate_translation_rmse_m << " m / " << t.ate_rotation_rmse_deg << " deg; smoothed "
              << smoothed.ate_translation_rmse_m << " m / " << smoothed.ate_rotation_rmse_deg
              << " deg\n";
  }
  pipeline::OnlineEstimationResult result;
  evaluation::CalibrationErrors c;
  evaluation::TrajectoryErrors t;
  evaluation::TrajectoryErrors smoothed;
  Eigen::Vector3d sigma_p_I_L_mm;
};

TEST(OnlineEstimationUrban60s, MeetsTheTrajectoryAndCalibrationGoals) {
  const UrbanRun run(60.0);
  const evaluation::CalibrationErrors& c = run.c;
  const evaluation::TrajectoryErrors& t = run.t;
  const evaluation::TrajectoryErrors& smoothed = run.smoothed;

  // Measured (reproducible whatever the thread count: docs/sliding_window.md, "Options"): 0.067
  // deg (yaw -0.066); x -6.1, y 0.2 mm with sigma 6.1 / 5.0 mm; offset -0.075 ms; radii 0.004 %;
  // lever arm 6.3 mm; T_I_V 0.41 deg (its roll all but unobserved). With the keyframes before
  // their sweeps (docs/estimation.md, Eq. P1c): 0.058 deg, x -5.1, y 4.6 mm, offset -0.12 ms,
  // lever arm 7.3 mm. Before the wheel rows' propagated
  // velocity and lever-arm variances (Eq. W7): 0.059 deg, x -5.2, y 4.0 mm, lever arm 7.1 mm. With
  // planes of five map points: 0.061 deg, x -8.4, y 2.3 mm (seeds 2 and 3 then: 0.020 / 0.041 deg,
  // x and y within 5.5 / 1.9 mm, -0.05 / 0.06 ms, lever arm 11.1 / 7.3 mm).
  EXPECT_LT(c.T_I_L.RotationAngleDeg(), 0.1);
  // The excited axes of the translation. 60 s of this drive determine them to about 6 mm (the
  // batch solution on this log: x -12.7 mm), too little for a sure 1 cm, which the 120 s
  // test below checks; here the error stays within three of the window's own sigmas.
  ASSERT_TRUE(run.sigma_p_I_L_mm.allFinite());
  EXPECT_LT(run.sigma_p_I_L_mm.head<2>().maxCoeff(), 8.0);
  EXPECT_LT(std::abs(c.T_I_L.translation_mm.x()), 3.0 * run.sigma_p_I_L_mm.x());
  EXPECT_LT(std::abs(c.T_I_L.translation_mm.y()), 3.0 * run.sigma_p_I_L_mm.y());
  EXPECT_LT(std::abs(c.time_offset_ms), 0.5);
  EXPECT_LT(std::abs(c.wheel_radius_left_percent), 0.1);
  EXPECT_LT(std::abs(c.wheel_radius_right_percent), 0.1);
  EXPECT_LT(c.p_I_A_mm.norm(), 20.0);
  EXPECT_LT(c.T_I_V.RotationAngleDeg(), 1.0);
  // One gyro sample per wheel row put the rear axle 40 cm too high (docs/sliding_window.md, "Wheel
  // rows": gyro mean).
  EXPECT_LT(c.T_I_V.translation_mm.norm(), 100.0);
  EXPECT_EQ(t.unmatched_poses, 0);
  // The trajectory goals hold for the smoothed trajectory (docs/sliding_window.md,
  // "Smoothing"). Measured: 0.8 cm / 0.075 deg (0.068 deg with the keyframes before their
  // sweeps; seeds 2 and 3 with five-point planes: 0.7 / 0.9
  // cm, 0.059 / 0.068 deg); what remains is mostly a constant yaw that the batch solution
  // shares: the extrinsic's yaw error mirrored (docs/evaluation.md, "Trajectory").
  EXPECT_EQ(smoothed.unmatched_poses, 0);
  EXPECT_LT(smoothed.ate_translation_rmse_m, 0.05);
  EXPECT_LT(smoothed.ate_rotation_rmse_deg, 0.1);
  // Its roll and pitch alone (tilt, which no yaw alignment moves): measured 0.024 deg (0.026
  // with the farthest partners nine keyframes apart instead of ten), the batch's trajectory
  // 0.011 deg. With the nearest partners walked first once the extrinsic settled (5 keyframes
  // apart) it was 0.039 deg: the tilt drifted with the biases on the straight after the last
  // turn (docs/sliding_window.md, "Partner walk").
  EXPECT_LT(smoothed.tilt_rmse_deg, 0.03);
  // The filtered trajectory (each keyframe as it left the window) has seen no later data:
  // the roll while the accelerometer bias and gravity are still being told apart before the
  // first turn, and the yaw. Measured 1.8 cm / 0.116 deg (0.129 deg with the keyframes before
  // their sweeps; five-point planes: 1.6 cm / 0.124
  // deg; seeds 2 and 3: 4.2 / 2.6 cm, 0.142 / 0.118 deg).
  EXPECT_LT(t.ate_translation_rmse_m, 0.05);
  EXPECT_LT(t.ate_rotation_rmse_deg, 0.2);
}

// The extrinsic's goals on twice the drive: its translation's variance halves (sigma 3.8 /
// 3.4 mm). Measured: x -4.3, y -2.5 mm; 0.035 deg; offset -0.11 ms; smoothed ATE 0.9 cm /
// 0.048 deg (with the keyframes before their sweeps, Eq. P1c: x -3.3, y 0.8 mm, 0.029 deg,
// 0.041 deg; with five-point planes: x -5.3, y 1.5 mm; 0.034 deg; 0.046 deg). Before the window's
// residual range limit (docs/sliding_window.md, "Far points"): x -7.1, y 1.6 mm, 0.035 deg; seeds
// 2-5 x and y within 5.8 / 3.4 mm, 0.015-0.050 deg.
TEST(OnlineEstimationUrban120s, MeetsTheExtrinsicAndTimeOffsetGoals) {
  const UrbanRun run(120.0);
  const evaluation::CalibrationErrors& c = run.c;
  EXPECT_LT(c.T_I_L.RotationAngleDeg(), 0.1);
  EXPECT_LT(std::abs(c.T_I_L.translation_mm.x()), 10.0);  // the excited axes
  EXPECT_LT(std::abs(c.T_I_L.translation_mm.y()), 10.0);
  EXPECT_LT(std::abs(c.time_offset_ms), 0.5);
  EXPECT_LT(std::abs(c.wheel_radius_left_percent), 0.1);
  EXPECT_LT(std::abs(c.wheel_radius_right_percent), 0.1);
  EXPECT_LT(run.smoothed.ate_translation_rmse_m, 0.05);
  EXPECT_LT(run.smoothed.ate_rotation_rmse_deg, 0.1);
}

}  // namespace
}  // namespace autocal
