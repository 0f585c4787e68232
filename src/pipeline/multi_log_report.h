#pragma once

// The repeatability table of several logs (repeatability.csv and the report's section) and the
// report of a multi-log calibration (report.html, docs/report.md "Several logs").

#include <string>
#include <vector>

#include "autocal/pipeline/multi_log_calibration.h"

namespace autocal {
namespace pipeline {

// One log's estimate of one block direction, in display units; a rotation's value is its
// rotation vector component from the shared rotation.
struct RepeatabilityEntry {
  std::string log;
  double value = 0.0;
  // A log's before any direction was held (its estimate's); the shared one's as calibration.yaml
  // reports it, after holding (Eq. C2), with the reported value.
  double sigma = 0.0;
};

// One block direction: every log's estimate that has the block, and the shared one.
struct RepeatabilityRow {
  const BlockRepeatability* block = nullptr;
  std::string key, direction, unit;
  std::vector<RepeatabilityEntry> logs;
  RepeatabilityEntry shared;
};
std::vector<RepeatabilityRow> RepeatabilityRows(const MultiLogCalibrationResult& result);

// One self-contained page: the shared calibration, the repeatability table with the test per
// block, the findings and warnings, and a link to each log's own report.
std::string MultiLogReportHtml(const MultiLogCalibrationResult& result);

}  // namespace pipeline
}  // namespace autocal
