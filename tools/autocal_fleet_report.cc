// autocal_fleet_report: gathers the result directories of many autocal_calibrate runs (a
// Slurm job array, GNU parallel) into one table and one HTML overview (docs/fleet.md).
//
//   autocal_fleet_report --output=DIR RESULT_DIR [RESULT_DIR ...]
//   autocal_fleet_report --output=DIR --results_file=LIST
//
// Writes DIR/fleet.csv and DIR/fleet.html: per vehicle the estimated values and sigma, the
// vehicles far from the fleet's median, and the failed runs with their messages. Exit status
// 0 when every run calibrated, 2 when some failed (the report is written all the same), 1 on
// bad input.

#include <gflags/gflags.h>

#include <iostream>

#include "autocal/common/error.h"
#include "autocal/io/output_files.h"
#include "autocal/pipeline/fleet_report.h"
#include "tool_checks.h"
#include "tool_help.h"

DEFINE_string(output, "",
              "report directory; required (fleet.csv, fleet.html); apart from the result "
              "directories (not one of them, inside one or holding one)");
DEFINE_string(results_file, "",
              "a file listing result directories, one per line (# comments); added to the "
              "directories given as arguments");

int main(int argc, char** argv) {
  gflags::SetUsageMessage(
      "autocal_fleet_report --output=DIR RESULT_DIR [RESULT_DIR ...]\n"
      "Gathers autocal_calibrate results (status.yaml, calibration.yaml) into fleet.csv and "
      "fleet.html.");
  if (autocal::tools::ShowShortHelpIfAsked(argc, argv, "autocal_fleet_report")) return 0;
  gflags::ParseCommandLineFlags(&argc, &argv, true);
  try {
    std::vector<std::string> directories(argv + 1, argv + argc);
    if (!FLAGS_results_file.empty()) {
      for (const std::string& d :
           autocal::tools::ReadListFile(FLAGS_results_file, "--results_file")) {
        directories.push_back(d);
      }
    }
    if (FLAGS_output.empty() || directories.empty()) {
      throw autocal::Error("--output and at least one result directory are required (see --help)");
    }
    // The report replaces --output whole: a result directory there would be lost.
    autocal::tools::CheckOutputApartFromInputs(FLAGS_output, "--output", directories);
    autocal::io::CheckOutputDirectory(FLAGS_output, autocal::io::OutputKind::kResult);
    const autocal::pipeline::FleetReport report = autocal::pipeline::GatherFleet(directories);
    autocal::io::StagedDirectory out(FLAGS_output, autocal::io::OutputKind::kResult);
    autocal::io::WriteFileAtomically(out.File("fleet.csv"), autocal::pipeline::FleetCsv(report));
    autocal::io::WriteFileAtomically(out.File("fleet.html"),
                                     autocal::pipeline::FleetReportHtml(report));
    out.Commit();
    std::cout << report.entries.size() << " runs: " << report.succeeded << " calibrated, "
              << report.entries.size() - report.succeeded << " failed\n";
    for (const autocal::pipeline::FleetEntry& e : report.entries) {
      if (!e.calibration) std::cout << "failed: " << e.vehicle << ": " << e.failure << "\n";
    }
    for (const autocal::pipeline::FleetOutlier& o : report.outliers) {
      std::cout << "outlier: " << o.text << "\n";
    }
    std::cout << "written: " << FLAGS_output << "/fleet.csv, fleet.html\n";
    return report.succeeded == report.entries.size() ? 0 : 2;
  } catch (const autocal::Error& e) {
    std::cerr << "autocal_fleet_report: " << e.what() << "\n";
    return 1;
  }
}
