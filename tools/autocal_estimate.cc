// autocal_estimate: online estimation of a recorded dataset with the sliding window.
//
//   autocal_estimate --dataset=DIR --problem=problems/urban_full.yaml --output=DIR
//
// Initializes the state and LiDAR-IMU calibration from the first seconds of the log (without
// the LiDAR: the state from GNSS and the IMU, keyframes at the GNSS period), then streams the
// IMU, wheel, GNSS and LiDAR data in arrival order through the sliding-window estimator, and
// writes trajectory.tum (every keyframe as it left the window),
// trajectory_smoothed.tum (the same keyframes smoothed from the final window), states.csv
// (every keyframe's pose, velocity and biases), calibration_over_time.csv (the estimate after
// every keyframe) and calibration.yaml (final values with sigma) into --output
// (docs/sliding_window.md, "Streaming a dataset").

#include <gflags/gflags.h>

#include <cstdio>
#include <iostream>
#include <string>

#include "autocal/common/error.h"
#include "autocal/common/format.h"
#include "autocal/common/units.h"
#include "autocal/geometry/so3.h"
#include "autocal/io/dataset.h"
#include "autocal/io/output_files.h"
#include "autocal/io/problem_yaml.h"
#include "autocal/pipeline/offline_calibration.h"
#include "autocal/pipeline/online_estimation.h"
#include "keep_freed_memory.h"
#include "tool_checks.h"
#include "tool_help.h"

DEFINE_string(dataset, "", "dataset directory (format: datasets/README.md); required");
DEFINE_string(problem, "",
              "problem file (problems/*.yaml: sensors, blocks, losses, window "
              "size, solver, LiDAR points); required");
DEFINE_string(output, "",
              "result directory: trajectory.tum, trajectory_smoothed.tum, states.csv, "
              "calibration_over_time.csv, calibration.yaml, timings.yaml; required, apart from the "
              "dataset and the problem file (neither holding nor inside them). Written whole "
              "at the end (a stopped run leaves only OUTPUT.partial-XXXXXX); an existing one is "
              "replaced only when it holds nothing but result files, otherwise refused");
DEFINE_int32(threads, 0,
             "threads for reading sweeps and the window's association; 0: the problem file's "
             "solver.num_threads (docs/calibration.md, \"Reproducibility and threads\")");
DEFINE_double(init_duration_s, 30.0,
              "seconds of the log (from its first sweep) given to the "
              "initializer that starts the window; > 0 and at most 1e9");
DEFINE_int32(init_sweep_stride, 3,
             "every n-th sweep of those seconds goes to the initializer; "
             ">= 1");
DEFINE_int32(scatter_stretches, 32,
             "spans of the stream between whose ends the estimate's steps are tested against "
             "its covariance; the sigmas are widened where they scatter more "
             "(docs/sliding_window.md, Eq. W9); 0: no test; at most 1000");
DEFINE_int32(progress_every, 10, "print the calibration every this many keyframes (0: never)");

namespace {

// --init_duration_s and --init_sweep_stride, before the dataset is read. A duration is turned
// into int64 nanoseconds: beyond 1e9 s (31 years) it overflows and takes no sweep.
void CheckInitializationFlags() {
  if (!(FLAGS_init_duration_s > 0.0) || !(FLAGS_init_duration_s <= 1e9)) {
    throw autocal::Error("--init_duration_s must be a positive number of seconds up to 1e9, got " +
                         autocal::FormatShort(FLAGS_init_duration_s));
  }
  if (FLAGS_init_sweep_stride < 1) {
    throw autocal::Error("--init_sweep_stride must be at least 1, got " +
                         std::to_string(FLAGS_init_sweep_stride));
  }
}

// Every flag and the output location, before any work: the result replaces --output whole,
// so the dataset or the problem file in it would be lost with it.
void CheckFlags(int argc, char** argv) {
  if (argc > 1) throw autocal::Error(std::string("unexpected argument '") + argv[1] + "'");
  if (FLAGS_dataset.empty() || FLAGS_problem.empty() || FLAGS_output.empty()) {
    throw autocal::Error("--dataset, --problem and --output are required (see --help)");
  }
  if (FLAGS_progress_every < 0) throw autocal::Error("--progress_every must be >= 0");
  autocal::tools::CheckScatterStretchesFlag(FLAGS_scatter_stretches, 3);
  CheckInitializationFlags();
  autocal::tools::CheckOutputApartFromInputs(FLAGS_output, "--output",
                                             {FLAGS_dataset, FLAGS_problem});
  autocal::io::CheckOutputDirectory(FLAGS_output, autocal::io::OutputKind::kResult);
  autocal::tools::CheckDatasetDirectory(FLAGS_dataset);
}

// The wheel blocks of the dataset's form, in words.
std::string WheelBlocks(autocal::sensors::WheelForm form, const autocal::sensors::Calibration& c) {
  char text[96];
  switch (form) {
    case autocal::sensors::WheelForm::kSpeedYawRate:
      std::snprintf(text, sizeof(text), "k_v %.4f  b_eff %.4f m", c.odometry_speed_scale,
                    c.effective_track_m);
      break;
    case autocal::sensors::WheelForm::kLinearSpeeds:
      std::snprintf(text, sizeof(text), "speed scales %.4f %.4f  track %.4f m",
                    c.wheel_speed_scale_left, c.wheel_speed_scale_right, c.track_width_m);
      break;
    case autocal::sensors::WheelForm::kAngularRates:
      std::snprintf(text, sizeof(text), "radii %.4f %.4f m  track %.4f m", c.wheel_radius_left_m,
                    c.wheel_radius_right_m, c.track_width_m);
      break;
  }
  return std::string(text);
}

// One line every --progress_every keyframes: the blocks the stream moves most.
void PrintProgress(const autocal::pipeline::OnlineEstimationProgress& p, bool lidar,
                   autocal::sensors::WheelForm form) {
  if (p.updates % FLAGS_progress_every != 0) return;
  const autocal::sensors::Calibration& c = p.calibration;
  if (!lidar) {
    std::fprintf(stderr, "%5.1f %%  keyframe %lld  update %.0f ms  %s  p_I_A [%.3f %.3f %.3f] m\n",
                 100.0 * p.log_fraction, static_cast<long long>(p.updates), 1e3 * p.update_s,
                 WheelBlocks(form, c).c_str(), c.p_I_A.x(), c.p_I_A.y(), c.p_I_A.z());
    return;
  }
  const Eigen::Vector3d r_deg = autocal::geometry::Log(c.q_I_L) * autocal::kRadToDeg;
  std::fprintf(stderr,
               "%5.1f %%  keyframe %lld  update %.0f ms  q_I_L [%.3f %.3f %.3f] deg  "
               "p_I_L [%.3f %.3f %.3f] m  offset %.2f ms\n",
               100.0 * p.log_fraction, static_cast<long long>(p.updates), 1e3 * p.update_s,
               r_deg.x(), r_deg.y(), r_deg.z(), c.p_I_L.x(), c.p_I_L.y(), c.p_I_L.z(),
               1e3 * c.time_offset_lidar_imu_s);
}

// The final values as autocal_calibrate prints its own (value, sigma and observability per
// direction), then the warnings and the files written.
void PrintSummary(const autocal::pipeline::OnlineEstimationResult& result, bool lidar) {
  std::cout << "keyframes " << result.trajectory.size() << ", marginalized "
            << result.counters.marginalizations << ", " << result.seconds_total
            << " s (initialization " << result.seconds_initialization << " s)\n";
  if (!lidar) std::cout << "keyframe period " << result.keyframe_period_s << " s\n";
  std::cout << autocal::pipeline::FormatCalibrationValues(result.calibration);
  for (const std::string& w : result.warnings) std::cout << "warning: " << w << "\n";
  std::cout << "written: " << FLAGS_output
            << "/trajectory.tum, trajectory_smoothed.tum, states.csv, calibration_over_time.csv, "
               "calibration.yaml, timings.yaml, warnings.txt\n";
}

}  // namespace

int main(int argc, char** argv) {
  autocal::tools::StartWithHugePageHeap(argv);
  gflags::SetUsageMessage(
      "autocal_estimate --dataset=DIR --problem=problems/X.yaml --output=DIR\n"
      "Streams a recorded log through the online sliding-window estimator.");
  if (autocal::tools::ShowShortHelpIfAsked(argc, argv, "autocal_estimate")) return 0;
  gflags::ParseCommandLineFlags(&argc, &argv, true);
  autocal::tools::KeepFreedMemory();
  try {
    CheckFlags(argc, argv);
    autocal::io::Problem problem = autocal::io::ReadProblemYaml(FLAGS_problem);
    autocal::tools::ApplyThreadsFlag(FLAGS_threads, &problem);
    const autocal::io::Dataset dataset = autocal::io::ReadDataset(FLAGS_dataset);
    autocal::pipeline::OnlineEstimationOptions options;
    options.initialization_duration_s = FLAGS_init_duration_s;
    options.initializer_sweep_stride = FLAGS_init_sweep_stride;
    options.scatter_stretches = FLAGS_scatter_stretches;
    const bool lidar = problem.sensors.lidar;
    const autocal::sensors::WheelForm form = dataset.wheel_form();
    if (FLAGS_progress_every > 0) {
      options.progress = [lidar, form](const autocal::pipeline::OnlineEstimationProgress& p) {
        PrintProgress(p, lidar, form);
      };
    }
    std::fprintf(stderr, "initializing from the first %.0f s ...\n", FLAGS_init_duration_s);
    const autocal::pipeline::OnlineEstimationResult result =
        autocal::pipeline::EstimateDatasetOnline(dataset, problem, options);
    autocal::pipeline::WriteOnlineEstimationResult(FLAGS_output, result);
    PrintSummary(result, lidar);
  } catch (const autocal::Error& e) {
    std::cerr << "autocal_estimate: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
