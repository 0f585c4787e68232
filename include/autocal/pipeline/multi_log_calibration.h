#pragma once

// Several logs of one vehicle calibrated together (docs/calibration.md, "Several logs"):
//   1. each log alone, as CalibrateDataset does: its own estimate, kept for comparison;
//   2. one shared calibration from the logs' posteriors (estimation/calibration_fusion.h,
//      Eq. M1-M2), whose directions no log excited are held at their prior as for one log;
//   3. each log's trajectory solved at the shared calibration;
//   4. the repeatability: per block, whether the logs agree with one true value (Eq. M3), and
//      in words where they do not ("the right rear wheel radius changed by 0.40 % between ...:
//      tyre pressure or wear?").
// This is what autocal_calibrate runs when given more than one dataset.

#include <string>
#include <vector>

#include "autocal/estimation/calibration_fusion.h"
#include "autocal/io/calibration_yaml.h"
#include "autocal/io/dataset.h"
#include "autocal/io/problem_yaml.h"
#include "autocal/io/run_status.h"
#include "autocal/pipeline/offline_calibration.h"

namespace autocal {
namespace pipeline {

struct MultiLogCalibrationOptions {
  OfflineCalibrationOptions calibration;  // for every log's solves
  // The chance that logs which do share one calibration have any block flagged: each of the
  // m blocks tested (Eq. M3) is flagged below a p-value of this over m (Bonferroni), so that a
  // fleet's reports do not fill with false findings as blocks are added.
  double min_agreement_p_value = 0.01;
  // Empty, or one per dataset in their order: that log's set_to_truth for its own solve
  // (evaluation::TruthSetter of a simulated log), so that its own result carries the
  // Cramer-Rao bound (LogCalibration::own.bound). calibration.set_to_truth, one setter for
  // every log, is refused: a log's truth is its own.
  std::vector<estimation::StateSetter> set_to_truth;
};

struct LogCalibration {
  std::string name;  // unique among the logs: the dataset directory's name
  std::string dataset_directory;
  OfflineCalibrationResult own;  // the log alone (step 1)
  // Its trajectory at the shared calibration, every block fixed; its warnings are the shared
  // result's too, named by the log.
  OfflineCalibrationResult at_shared;
};

// One block's repeatability: the test and, when it fails, the finding in words.
struct BlockRepeatability {
  estimation::BlockAgreement agreement;
  std::string name;          // the block in words
  double p_threshold = 0.0;  // flagged below this p-value
  bool agree = true;
  std::string finding;  // empty when the logs agree
};

struct MultiLogCalibrationResult {
  io::CalibrationFile calibration;     // shared: values, sigma and observability
  estimation::FusedCalibration fused;  // before holding; blocks' data not bound
  // The shared calibration's held directions and sigmas (Eq. C1-C2), per block of fused.blocks:
  // the sigmas calibration.yaml reports.
  estimation::BlockObservability observability;
  std::vector<LogCalibration> logs;
  std::vector<BlockRepeatability> repeatability;
  // The shared calibration's, each log's at the shared calibration, then the findings.
  std::vector<std::string> warnings;
  double seconds_total = 0.0;
};

// Throws autocal::Error naming the log when one cannot be calibrated, or when the logs
// cannot be combined (no covariance). Fewer than two datasets, one directory given twice
// (its data would count twice), or set_to_truth options that do not match the datasets are
// refused.
MultiLogCalibrationResult CalibrateDatasets(const std::vector<io::Dataset>& datasets,
                                            const io::Problem& problem,
                                            const MultiLogCalibrationOptions& options = {});

// Into `directory` (written whole): calibration.yaml (shared), repeatability.csv (every log's
// estimate, the shared one and the test per block), report.html, and per log
// logs/<name>/trajectory.tum (at the shared calibration) and logs/<name>/own/ (the log alone,
// as WriteCalibrationResult writes it), and status.yaml when `status` is given.
void WriteMultiLogResult(const std::string& directory, const MultiLogCalibrationResult& result,
                         const io::RunStatus* status = nullptr);

// repeatability.csv: one row per log (and "shared") and block direction: value and sigma in
// display units, then the block's chi-square, degrees of freedom, p-value and agreement. The
// log's name is quoted as fleet.csv quotes text (CsvText).
std::string RepeatabilityCsv(const MultiLogCalibrationResult& result);

// The terminal summary: the shared calibration as FormatCalibrationSummary prints one, then
// one line per block's repeatability and the findings.
std::string FormatMultiLogSummary(const MultiLogCalibrationResult& result);

}  // namespace pipeline
}  // namespace autocal
