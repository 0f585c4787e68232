// autocal_calibrate: offline calibration of one recorded dataset, or of several logs of one
// vehicle in one solve.
//
//   autocal_calibrate --dataset=DIR --problem=problems/urban_full.yaml --output=DIR
//   autocal_calibrate --dataset=A --dataset=B [--datasets_file=LIST] --problem=... --output=DIR
//
// Loads and validates the dataset against the problem, initializes the calibration without a
// hand-measured guess, solves the whole log in one batch, and writes calibration.yaml (values,
// sigma, observability), trajectory.tum and calibration_per_iteration.csv into --output. With
// several datasets: one shared calibration, each log's trajectory at it and its own estimate,
// and their repeatability (docs/calibration.md, "Several logs"). Every run that reaches its
// output leaves status.yaml there, also when it fails, unless a failed run finds a previous
// result there: that result stays as it was (docs/fleet.md).

#include <gflags/gflags.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <string>
#include <system_error>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/time.h"
#include "autocal/evaluation/information_bound.h"
#include "autocal/io/dataset.h"
#include "autocal/io/output_files.h"
#include "autocal/io/problem_yaml.h"
#include "autocal/io/run_status.h"
#include "autocal/pipeline/fleet_report.h"
#include "autocal/pipeline/multi_log_calibration.h"
#include "autocal/pipeline/offline_calibration.h"
#include "keep_freed_memory.h"
#include "tool_checks.h"
#include "tool_help.h"

DEFINE_string(dataset, "",
              "dataset directory (format: datasets/README.md); required unless --datasets_file. "
              "Given more than once (on the command line or in a flag file): several logs of "
              "one vehicle, one shared calibration");
DEFINE_string(datasets_file, "",
              "a file listing dataset directories, one per line (# comments); added to --dataset");
DEFINE_string(problem, "", "problem file (problems/*.yaml: sensors, blocks, losses); required");
DEFINE_string(
    output, "",
    "result directory; required, apart from the inputs (neither holding nor inside a "
    "dataset, nor holding the problem file). Written whole at the end (a stopped run leaves only "
    "OUTPUT.partial-XXXXXX); an existing one is replaced only when it holds nothing but "
    "result files, otherwise refused. A failed run leaves status.yaml alone there when it held "
    "no result; a previous result stays as it was");
DEFINE_string(vehicle, "",
              "the vehicle's label in status.yaml, for autocal_fleet_report; default: the first "
              "dataset directory's name");
DEFINE_int32(threads, 0,
             "threads for reading sweeps, the odometry and the Ceres solves; 0: the problem "
             "file's solver.num_threads. autocal's own sums do not depend on the count; Ceres' "
             "per-thread sums can, at rounding level (docs/calibration.md, \"Reproducibility "
             "and threads\")");
DEFINE_int32(scatter_stretches, 16,
             "stretches of the log over which each sensor's rows are tested for scatter beyond "
             "their noise model; the sigmas are widened where it exceeds chance "
             "(docs/calibration.md, Eq. C8); 0: no test; at most 1000. A sensor with fewer rows "
             "than stretches is not tested");
DEFINE_bool(progress, true, "print the stage, percent, cost and time left while running");
DEFINE_bool(bound, true,
            "with a ground truth in the dataset (a simulated log): the Cramer-Rao bound of the "
            "estimated blocks in the report, next to their sigma (docs/evaluation.md); with "
            "several logs, in each log's own report");

namespace {

// True while a progress line without its line break is on the terminal.
bool progress_line_open = false;

void PrintProgress(const autocal::pipeline::CalibrationProgress& p) {
  std::fprintf(stderr, "\r%-16s %5.1f %%", p.stage.c_str(), 100.0 * p.fraction);
  if (p.cost > 0.0) std::fprintf(stderr, "  cost %.4g", p.cost);
  if (p.seconds_left > 0.0) std::fprintf(stderr, "  ~%.0f s left", p.seconds_left);
  std::fprintf(stderr, "   %s", p.fraction >= 1.0 ? "\n" : "");
  progress_line_open = p.fraction < 1.0;
  std::fflush(stderr);
}

void EndProgressLine() {
  if (progress_line_open) std::fputc('\n', stderr);
  progress_line_open = false;
}

std::string VehicleLabel(const std::vector<std::string>& datasets) {
  if (!FLAGS_vehicle.empty() || datasets.empty()) return FLAGS_vehicle;
  return autocal::pipeline::DirectoryName(datasets.front());
}

void CalibrateOne(const std::string& directory, const autocal::io::Problem& problem,
                  autocal::pipeline::OfflineCalibrationOptions options,
                  std::chrono::steady_clock::time_point start, autocal::io::RunStatus* status) {
  const autocal::io::Dataset dataset = autocal::io::ReadDataset(directory);
  if (FLAGS_bound) options.set_to_truth = autocal::evaluation::TruthSetter(dataset);
  const autocal::pipeline::OfflineCalibrationResult result =
      autocal::pipeline::CalibrateDataset(dataset, problem, options);
  EndProgressLine();
  status->seconds = autocal::SecondsSince(start);
  autocal::pipeline::WriteCalibrationResult(FLAGS_output, result, status);
  std::cout << autocal::pipeline::FormatCalibrationSummary(result);
  std::cout << "written: " << FLAGS_output << "/calibration.yaml, trajectory.tum, "
            << "calibration_per_iteration.csv, timings.yaml, report.html, warnings.txt, "
               "status.yaml\n";
}

void CalibrateSeveral(const std::vector<std::string>& directories,
                      const autocal::io::Problem& problem,
                      const autocal::pipeline::OfflineCalibrationOptions& options,
                      std::chrono::steady_clock::time_point start, autocal::io::RunStatus* status) {
  std::vector<autocal::io::Dataset> datasets;
  for (const std::string& d : directories) datasets.push_back(autocal::io::ReadDataset(d));
  autocal::pipeline::MultiLogCalibrationOptions multi;
  multi.calibration = options;
  if (FLAGS_bound) {  // each log's own result against its own truth
    for (const autocal::io::Dataset& d : datasets) {
      multi.set_to_truth.push_back(autocal::evaluation::TruthSetter(d));
    }
  }
  const autocal::pipeline::MultiLogCalibrationResult result =
      autocal::pipeline::CalibrateDatasets(datasets, problem, multi);
  EndProgressLine();
  status->seconds = autocal::SecondsSince(start);
  autocal::pipeline::WriteMultiLogResult(FLAGS_output, result, status);
  std::cout << autocal::pipeline::FormatMultiLogSummary(result);
  std::cout << "written: " << FLAGS_output << "/calibration.yaml, repeatability.csv, report.html, "
            << "warnings.txt, status.yaml, logs/<log>/trajectory.tum and logs/<log>/own/\n";
}

// True when `directory` holds a result: anything but a failed run's status.yaml. A directory
// that cannot be listed counts as one (its content is kept).
bool HoldsAResult(const std::string& directory) {
  namespace fs = std::filesystem;
  std::error_code error;
  fs::directory_iterator it(directory, error);
  if (error) return fs::exists(directory, error);
  for (; !error && it != fs::directory_iterator(); it.increment(error)) {
    if (it->path().filename() != "status.yaml") return true;
  }
  return static_cast<bool>(error);
}

// A run that failed after its flags, dataset directories, problem file and output were
// checked leaves status.yaml alone there, so that a batch of runs can be gathered, unless
// --output holds a previous result: bad input loses nothing, so that result stays as it was
// (docs/fleet.md). A failure to write the status is reported, not hidden.
void WriteFailureStatus(autocal::io::RunStatus status, const std::string& message, double seconds) {
  if (HoldsAResult(FLAGS_output)) {
    std::cerr << "autocal_calibrate: the previous result in '" << FLAGS_output
              << "' is kept as it was; this failure is not recorded there\n";
    return;
  }
  status.exit_status = 1;
  status.message = message;
  status.seconds = seconds;
  try {
    autocal::io::StagedDirectory out(FLAGS_output, autocal::io::OutputKind::kResult);
    autocal::io::WriteRunStatus(out.File("status.yaml"), status);
    out.Commit();
  } catch (const autocal::Error& e) {
    std::cerr << "autocal_calibrate: status.yaml not written: " << e.what() << "\n";
  }
}

}  // namespace

int main(int argc, char** argv) {
  autocal::tools::StartWithHugePageHeap(argv);
  gflags::SetUsageMessage(
      "autocal_calibrate --dataset=DIR [--dataset=DIR ...] --problem=problems/X.yaml "
      "--output=DIR\n"
      "Calibrates the sensors of a recorded log, or of several logs of one vehicle together.");
  if (autocal::tools::ShowShortHelpIfAsked(argc, argv, "autocal_calibrate")) return 0;
  // status.yaml's wall time counts from here, success or failure alike.
  const auto start = std::chrono::steady_clock::now();
  // --dataset may be repeated, on the command line and in --flagfile files; gflags keeps the
  // last value only, so they are gathered before it parses.
  std::vector<std::string> given = autocal::tools::RepeatedFlagValues(
      autocal::tools::ArgumentsWithFlagfiles(argc, argv), "dataset");
  gflags::ParseCommandLineFlags(&argc, &argv, true);
  // A value gflags took from elsewhere (--fromenv=dataset, --tryfromenv) counts as well.
  if (!FLAGS_dataset.empty() &&
      std::find(given.begin(), given.end(), FLAGS_dataset) == given.end()) {
    given.push_back(FLAGS_dataset);
  }
  autocal::tools::KeepFreedMemory();
  autocal::io::RunStatus status;
  status.tool = "autocal_calibrate";
  bool output_checked = false;
  try {
    if (argc > 1) throw autocal::Error(std::string("unexpected argument '") + argv[1] + "'");
    std::vector<std::string> directories = given;
    if (!FLAGS_datasets_file.empty()) {
      for (const std::string& d :
           autocal::tools::ReadListFile(FLAGS_datasets_file, "--datasets_file")) {
        directories.push_back(d);
      }
    }
    if (directories.empty() || FLAGS_problem.empty() || FLAGS_output.empty()) {
      throw autocal::Error(
          "--dataset (or --datasets_file), --problem and --output are required (see --help)");
    }
    status.datasets = directories;
    status.vehicle = VehicleLabel(directories);
    // Everything that can be checked before the work starts is; a wrong flag, dataset
    // directory or problem file leaves nothing, and a previous result in --output as it was.
    autocal::tools::CheckThreadsFlag(FLAGS_threads);
    autocal::tools::CheckScatterStretchesFlag(FLAGS_scatter_stretches, 2);
    // The result replaces --output whole: a dataset or the problem file in it would be lost
    // with it, also by a failed run's status.yaml.
    std::vector<std::string> inputs = directories;
    inputs.push_back(FLAGS_problem);
    if (!FLAGS_datasets_file.empty()) inputs.push_back(FLAGS_datasets_file);
    autocal::tools::CheckOutputApartFromInputs(FLAGS_output, "--output", inputs);
    autocal::io::CheckOutputDirectory(FLAGS_output, autocal::io::OutputKind::kResult);
    for (const std::string& d : directories) autocal::tools::CheckDatasetDirectory(d);
    autocal::io::Problem problem = autocal::io::ReadProblemYaml(FLAGS_problem);
    autocal::tools::ApplyThreadsFlag(FLAGS_threads, &problem);
    output_checked = true;  // from here on a failure leaves its status.yaml
    autocal::pipeline::OfflineCalibrationOptions options;
    options.scatter_stretches = FLAGS_scatter_stretches;
    if (FLAGS_progress) options.progress = PrintProgress;
    if (directories.size() == 1) {
      CalibrateOne(directories.front(), problem, options, start, &status);
    } else {
      CalibrateSeveral(directories, problem, options, start, &status);
    }
  } catch (const autocal::Error& e) {
    std::cerr << (progress_line_open ? "\n" : "") << "autocal_calibrate: " << e.what() << "\n";
    if (output_checked) {
      WriteFailureStatus(status, e.what(), autocal::SecondsSince(start));
    }
    return 1;
  }
  return 0;
}
