#pragma once

// status.yaml: how one run of a tool ended, written into its output directory whether it
// succeeded or not, so that a batch of stateless runs (a Slurm job array, GNU parallel) can be
// gathered without their logs (docs/fleet.md). A failed run's directory holds this file alone.
//
//   format: autocal_status_1
//   tool: autocal_calibrate
//   vehicle: car_017
//   datasets:
//     - /data/car_017/2026-11-30
//   exit_status: 1
//   message: "dataset ...: the drive cannot initialize the calibration: ..."
//   seconds: 12.5

#include <string>
#include <vector>

namespace autocal {
namespace io {

struct RunStatus {
  std::string tool;
  std::string vehicle;  // the label the run was given
  std::vector<std::string> datasets;
  int exit_status = 0;   // 0: the result beside this file is complete
  std::string message;   // the error, when exit_status is not 0
  double seconds = 0.0;  // wall time from the tool's start (reading the logs included)
};

// Throws ParseError (file, line, column) on malformed content, autocal::Error when the file
// cannot be read.
RunStatus ReadRunStatus(const std::string& path);

// Written atomically (io/output_files.h). Throws autocal::Error on I/O failure.
void WriteRunStatus(const std::string& path, const RunStatus& status);

}  // namespace io
}  // namespace autocal
