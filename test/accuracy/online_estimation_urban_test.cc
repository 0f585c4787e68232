// The online estimator's accuracy suite (issue goals in docs/sliding_window.md, "Figures"):
// a 60 s simulated urban log (seed 1, default sensors) streamed through the sliding window
// from the simulator's nominal guess with the shipped problems/urban_full.yaml, compared with
// the simulator's truth.
#include <filesystem>
#include <iostream>
#include <string>

#include <gtest/gtest.h>

#include "autocal/evaluation/calibration_errors.h"
#include "autocal/evaluation/trajectory_errors.h"
#include "autocal/io/dataset.h"
#include "autocal/io/problem_yaml.h"
#include "autocal/pipeline/online_estimation.h"
#include "autocal/sim/simulator.h"
#include "pipeline/simulated_urban_dataset.h"

namespace autocal {
namespace {

TEST(OnlineEstimationUrban60s, MeetsTheTrajectoryAndCalibrationGoals) {
  sim::SimulationOptions sim_options;
  sim_options.scenario = sim::ScenarioType::kUrban;
  sim_options.duration_s = 60.0;
  sim_options.seed = 1;
  const test::SimulatedUrbanDataset data(sim_options, "online_urban_60s");
  const io::Dataset dataset = io::ReadDataset(data.directory);
  const io::Problem problem = io::ReadProblemYaml(
      (std::filesystem::path(AUTOCAL_SOURCE_DIR) / "problems" / "urban_full.yaml").string());

  const pipeline::OnlineEstimationResult result = pipeline::EstimateDatasetOnline(dataset, problem);
  const evaluation::CalibrationErrors c =
      evaluation::CompareCalibration(result.calibration.value, data.simulator.true_calibration());
  const evaluation::TrajectoryErrors t =
      evaluation::CompareTrajectory(result.trajectory, dataset.groundtruth_trajectory);
  const evaluation::TrajectoryErrors smoothed =
      evaluation::CompareTrajectory(result.smoothed_trajectory, dataset.groundtruth_trajectory);
  std::cout << result.trajectory.size() << " keyframes in " << result.seconds_total << " s; T_I_L "
            << c.T_I_L.rotation_deg.transpose() << " deg, " << c.T_I_L.translation_mm.transpose()
            << " mm; offset " << c.time_offset_ms << " ms; radii " << c.wheel_radius_left_percent
            << " / " << c.wheel_radius_right_percent << " %; lever arm " << c.p_I_A_mm.transpose()
            << " mm; T_I_V " << c.T_I_V.rotation_deg.transpose() << " deg; ATE "
            << t.ate_translation_rmse_m << " m / " << t.ate_rotation_rmse_deg << " deg; smoothed "
            << smoothed.ate_translation_rmse_m << " m / " << smoothed.ate_rotation_rmse_deg
            << " deg\n";

  // Measured (reproducible: docs/sliding_window.md, "Solver: threads"): 0.062 deg; x -0.5,
  // y -2.7 mm (z, which planar driving does not excite, -5.6 mm); offset -0.31 ms; radii
  // 0.001 %; lever arm (1.7, -3.4, -6.5) mm; T_I_V 0.76 deg (its roll all but unobserved).
  // Seeds 2 and 3: 0.038 / 0.032 deg, x and y within 5.4 / 0.7 mm, -0.05 / -0.03 ms, lever
  // arm 11.5 / 6.4 mm.
  EXPECT_LT(c.T_I_L.RotationAngleDeg(), 0.1);
  EXPECT_LT(std::abs(c.T_I_L.translation_mm.x()), 10.0);  // the excited axes
  EXPECT_LT(std::abs(c.T_I_L.translation_mm.y()), 10.0);
  EXPECT_LT(std::abs(c.time_offset_ms), 0.5);
  EXPECT_LT(std::abs(c.wheel_radius_left_percent), 0.1);
  EXPECT_LT(std::abs(c.wheel_radius_right_percent), 0.1);
  EXPECT_LT(c.p_I_A_mm.norm(), 20.0);
  EXPECT_LT(c.T_I_V.RotationAngleDeg(), 1.0);
  // One gyro sample per wheel row put the rear axle 40 cm too high (Eq. SW10).
  EXPECT_LT(c.T_I_V.translation_mm.norm(), 100.0);
  EXPECT_EQ(t.unmatched_poses, 0);
  // The trajectory goals hold for the smoothed trajectory (docs/sliding_window.md,
  // "Smoothing"). Measured: 0.9 cm / 0.074 deg (seeds 2 and 3: 0.7 / 0.8 cm, 0.087 / 0.050
  // deg); what remains is mostly a constant yaw (0.06 deg) that the batch solution shares.
  EXPECT_EQ(smoothed.unmatched_poses, 0);
  EXPECT_LT(smoothed.ate_translation_rmse_m, 0.05);
  EXPECT_LT(smoothed.ate_rotation_rmse_deg, 0.1);
  // The filtered trajectory (each keyframe as it left the window) has seen no later data:
  // the roll while the accelerometer bias and gravity are still being told apart before the
  // first turn, and the yaw. Measured 2.1 cm / 0.124 deg (seeds 2 and 3: 4.1 / 2.6 cm,
  // 0.163 / 0.111 deg).
  EXPECT_LT(t.ate_translation_rmse_m, 0.05);
  EXPECT_LT(t.ate_rotation_rmse_deg, 0.2);
}

}  // namespace
}  // namespace autocal
