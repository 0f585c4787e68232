// autocal_calibrate: offline calibration of a recorded dataset.
//
//   autocal_calibrate --dataset=DIR --problem=problems/urban_full.yaml --output=DIR
//
// Loads and validates the dataset against the problem, initializes the calibration without a
// hand-measured guess, solves the whole log in one batch, and writes calibration.yaml (values,
// sigma, observability), trajectory.tum and calibration_per_iteration.csv into --output.

#include <gflags/gflags.h>

#include <cstdio>
#include <iostream>

#include "autocal/common/error.h"
#include "autocal/io/dataset.h"
#include "autocal/io/output_files.h"
#include "autocal/io/problem_yaml.h"
#include "autocal/pipeline/offline_calibration.h"
#include "keep_freed_memory.h"
#include "tool_checks.h"
#include "tool_help.h"

DEFINE_string(dataset, "", "dataset directory (format: datasets/README.md); required");
DEFINE_string(problem, "", "problem file (problems/*.yaml: sensors, blocks, losses); required");
DEFINE_string(output, "",
              "result directory; required. Written whole at the end (a stopped run leaves only "
              "OUTPUT.partial-XXXXXX); an existing one is replaced only when it holds nothing but "
              "result files, otherwise refused");
DEFINE_int32(threads, 0,
             "threads for reading sweeps, the odometry and the Ceres solves; 0: the problem "
             "file's solver.num_threads. Byte-identical results run to run on one thread; other "
             "counts differ slightly (docs/calibration.md, \"Reproducibility and threads\")");
DEFINE_bool(progress, true, "print the stage, percent, cost and time left while running");

namespace {

// True while a progress line without its line break is on the terminal.
bool progress_line_open = false;

}  // namespace

int main(int argc, char** argv) {
  gflags::SetUsageMessage(
      "autocal_calibrate --dataset=DIR --problem=problems/X.yaml --output=DIR\n"
      "Calibrates the LiDAR-IMU extrinsic and time offset of a recorded log.");
  if (autocal::tools::ShowShortHelpIfAsked(argc, argv, "autocal_calibrate")) return 0;
  gflags::ParseCommandLineFlags(&argc, &argv, true);
  autocal::tools::KeepFreedMemory();
  try {
    if (argc > 1) throw autocal::Error(std::string("unexpected argument '") + argv[1] + "'");
    if (FLAGS_dataset.empty() || FLAGS_problem.empty() || FLAGS_output.empty()) {
      throw autocal::Error("--dataset, --problem and --output are required (see --help)");
    }
    // Everything that can be checked before the work starts is.
    autocal::io::CheckOutputDirectory(FLAGS_output, autocal::io::OutputKind::kResult);
    autocal::tools::CheckDatasetDirectory(FLAGS_dataset);
    autocal::io::Problem problem = autocal::io::ReadProblemYaml(FLAGS_problem);
    autocal::tools::ApplyThreadsFlag(FLAGS_threads, &problem);
    const autocal::io::Dataset dataset = autocal::io::ReadDataset(FLAGS_dataset);
    autocal::pipeline::OfflineCalibrationOptions options;
    if (FLAGS_progress) {
      options.progress = [](const autocal::pipeline::CalibrationProgress& p) {
        std::fprintf(stderr, "\r%-16s %5.1f %%", p.stage.c_str(), 100.0 * p.fraction);
        if (p.cost > 0.0) std::fprintf(stderr, "  cost %.4g", p.cost);
        if (p.seconds_left > 0.0) std::fprintf(stderr, "  ~%.0f s left", p.seconds_left);
        std::fprintf(stderr, "   %s", p.fraction >= 1.0 ? "\n" : "");
        progress_line_open = p.fraction < 1.0;
        std::fflush(stderr);
      };
    }
    const autocal::pipeline::OfflineCalibrationResult result =
        autocal::pipeline::CalibrateDataset(dataset, problem, options);
    if (progress_line_open) std::fputc('\n', stderr);
    progress_line_open = false;
    autocal::pipeline::WriteCalibrationResult(FLAGS_output, result);
    std::cout << autocal::pipeline::FormatCalibrationSummary(result);
    std::cout << "written: " << FLAGS_output << "/calibration.yaml, trajectory.tum, "
              << "calibration_per_iteration.csv, timings.yaml, report.html\n";
  } catch (const autocal::Error& e) {
    std::cerr << (progress_line_open ? "\n" : "") << "autocal_calibrate: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
