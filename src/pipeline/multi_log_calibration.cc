#include "autocal/pipeline/multi_log_calibration.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <optional>
#include <set>
#include <sstream>
#include <system_error>

#include "autocal/common/error.h"
#include "autocal/common/format.h"
#include "autocal/io/output_files.h"
#include "autocal/io/tum_trajectory.h"
#include "autocal/pipeline/fleet_report.h"
#include "autocal/sensors/calibration_blocks.h"
#include "calibration_steps.h"
#include "multi_log_report.h"
#include "problem_blocks.h"

namespace autocal {
namespace pipeline {
namespace {

using sensors::CalibrationBlockId;

// The dataset directories' names (DirectoryName), made unique where they repeat.
std::vector<std::string> LogNames(const std::vector<io::Dataset>& datasets) {
  std::vector<std::string> names;
  std::set<std::string> seen;
  for (size_t i = 0; i < datasets.size(); ++i) {
    std::string base = DirectoryName(datasets[i].directory);
    if (base.empty()) base = "log";
    // A taken name gets the log's position, then further numbers while that is taken too
    // ("day", "day", "day_2" gives day, day_2, day_2_3).
    std::string name = base;
    for (size_t n = i + 1; !seen.insert(name).second; ++n) {
      name = base + "_" + std::to_string(n);
    }
    names.push_back(name);
  }
  return names;
}

// One log given twice would count its data twice: a sigma 1/sqrt(2) of the truth's.
void RequireDistinct(const std::vector<io::Dataset>& datasets) {
  std::set<std::string> seen;
  for (const io::Dataset& d : datasets) {
    std::error_code error;
    std::filesystem::path path = std::filesystem::weakly_canonical(d.directory, error);
    if (error) path = std::filesystem::absolute(d.directory).lexically_normal();
    if (!seen.insert(path.string()).second) {
      throw Error("dataset " + d.directory +
                  " is given twice: one log counted twice would claim the certainty of two");
    }
  }
}

// Each log's truth is its own: one setter per dataset, or none.
void RequireTruthPerLog(const std::vector<io::Dataset>& datasets,
                        const MultiLogCalibrationOptions& options) {
  if (options.calibration.set_to_truth) {
    throw Error(
        "MultiLogCalibrationOptions: calibration.set_to_truth would set every log to one truth; "
        "give set_to_truth, one per dataset");
  }
  if (!options.set_to_truth.empty() && options.set_to_truth.size() != datasets.size()) {
    throw Error("MultiLogCalibrationOptions: set_to_truth must be empty or one per dataset, got " +
                std::to_string(options.set_to_truth.size()) + " for " +
                std::to_string(datasets.size()) + " datasets");
  }
}

// What a change of a block between logs may mean, after the course's notes on each sensor.
std::string LikelyCause(CalibrationBlockId id) {
  switch (id) {
    case CalibrationBlockId::kWheelRadiusLeft:
    case CalibrationBlockId::kWheelRadiusRight:
    case CalibrationBlockId::kWheelSpeedScaleLeft:
    case CalibrationBlockId::kWheelSpeedScaleRight:
    case CalibrationBlockId::kOdometrySpeedScale:
      return "tyre pressure or wear?";
    case CalibrationBlockId::kTrackWidth:
    case CalibrationBlockId::kEffectiveTrack:
      return "other tyres, load or ground (slip)?";
    case CalibrationBlockId::kLidarRotation:
    case CalibrationBlockId::kLidarTranslation:
      return "was the LiDAR remounted or knocked?";
    case CalibrationBlockId::kVehicleRotation:
    case CalibrationBlockId::kVehicleTranslation:
      return "was the IMU remounted?";
    case CalibrationBlockId::kGnssLeverArm:
      return "was the GNSS antenna moved?";
    case CalibrationBlockId::kTimeOffset:
    case CalibrationBlockId::kWheelTimeOffset:
    case CalibrationBlockId::kGnssTimeOffset:
      break;
  }
  return "did a driver, the clock synchronization or the recorder change?";
}

// "changed by +1.33 mm (+0.40 %)": the change in display units, and in percent of the first
// log's value for a positive scalar (a radius, a scale, a track).
std::string Change(const estimation::BlockAgreement& a,
                   const estimation::CalibrationPosterior& first) {
  const sensors::CalibrationBlockInfo& info = sensors::CalibrationBlock(a.id);
  std::ostringstream out;
  out << "changed by " << std::showpos << std::setprecision(3) << a.difference * info.display_scale
      << ' ' << info.display_unit;
  const double value = info.const_values(first.solved)[0];
  if (info.tangent_size == 1 && info.manifold == sensors::BlockManifold::kEuclidean &&
      value > 0.0 && a.id != CalibrationBlockId::kTimeOffset &&
      a.id != CalibrationBlockId::kWheelTimeOffset && a.id != CalibrationBlockId::kGnssTimeOffset) {
    out << " (" << std::fixed << std::setprecision(2) << 100.0 * a.difference / value << " %)";
  }
  return out.str();
}

std::vector<BlockRepeatability> Repeatability(
    const std::vector<LogCalibration>& logs,
    const std::vector<estimation::CalibrationPosterior>& posteriors, double min_p_value) {
  std::vector<BlockRepeatability> out;
  const std::vector<estimation::BlockAgreement> agreements =
      estimation::AgreementOfLogs(posteriors);
  // Bonferroni: min_p_value is the chance that any block of logs that do agree is flagged.
  const double threshold =
      min_p_value / static_cast<double>(std::max<size_t>(1, agreements.size()));
  for (const estimation::BlockAgreement& a : agreements) {
    const sensors::CalibrationBlockInfo& info = sensors::CalibrationBlock(a.id);
    BlockRepeatability r;
    r.agreement = a;
    r.name = info.name;
    r.p_threshold = threshold;
    r.agree = a.p_value >= threshold;
    if (!r.agree) {
      std::ostringstream finding;
      finding << info.name;
      if (info.tangent_size > 1) finding << " (" << info.direction_names[a.direction] << ")";
      finding << " " << Change(a, posteriors[a.log_a]) << " between " << logs[a.log_a].name
              << " and " << logs[a.log_b].name << ", " << FormatFixed(a.z, 1)
              << " sigma (chi-square " << FormatFixed(a.chi_square, 1) << " for "
              << a.degrees_of_freedom << " degrees of freedom, p " << std::setprecision(2)
              << a.p_value << "): " << LikelyCause(a.id);
      r.finding = finding.str();
    }
    out.push_back(r);
  }
  return out;
}

// The shared calibration's observability: as for one log (Eq. C1-C2), on the fused posterior.
void ConcludeShared(const estimation::FusedCalibration& fused, MultiLogCalibrationResult* result) {
  sensors::Calibration value = fused.value;
  std::vector<estimation::EstimatedBlock> blocks = fused.blocks;
  estimation::BindBlocks(&value, &blocks);
  result->observability = estimation::HoldUnobservableDirections(blocks, fused.covariance);
  const estimation::BlockObservability& observability = result->observability;
  result->calibration.value = value;
  FillUncertainty(blocks, observability, &result->calibration.uncertainty);
  result->calibration.solver["logs"] = std::to_string(result->logs.size());
  result->warnings.insert(result->warnings.end(), observability.warnings.begin(),
                          observability.warnings.end());
}

// Each log's trajectory at the shared calibration: its dataset with that calibration as the
// nominal one, every block fixed.
OfflineCalibrationResult SolveAtShared(const io::Dataset& dataset, const io::Problem& problem,
                                       const sensors::Calibration& shared,
                                       const OfflineCalibrationOptions& options) {
  io::Dataset at_shared = dataset;
  at_shared.sensors.nominal_calibration = shared;
  io::Problem fixed = problem;
  fixed.calibration = io::WithEveryBlockFixed(problem.calibration);
  // The run fixes the blocks, not the problem file: a move says that the log's data disagree
  // with the shared value.
  OfflineCalibrationOptions at_shared_options = options;
  at_shared_options.fixed_block_advice = ": this log's data disagree with the shared value";
  return CalibrateDataset(at_shared, fixed, at_shared_options);
}

}  // namespace

MultiLogCalibrationResult CalibrateDatasets(const std::vector<io::Dataset>& datasets,
                                            const io::Problem& problem,
                                            const MultiLogCalibrationOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  if (datasets.size() < 2) {
    throw Error("several logs need at least two datasets, got " + std::to_string(datasets.size()));
  }
  RequireDistinct(datasets);
  RequireTruthPerLog(datasets, options);
  MultiLogCalibrationResult result;
  const std::vector<std::string> names = LogNames(datasets);
  std::vector<estimation::CalibrationPosterior> posteriors;
  for (size_t i = 0; i < datasets.size(); ++i) {
    LogCalibration log;
    log.name = names[i];
    log.dataset_directory = datasets[i].directory;
    OfflineCalibrationOptions own = options.calibration;
    if (!options.set_to_truth.empty()) own.set_to_truth = options.set_to_truth[i];
    log.own = CalibrateDataset(datasets[i], problem, own);
    if (!log.own.posterior.covariance.ok) {
      throw Error("log " + log.name + " (" + datasets[i].directory +
                  "): the covariance of its calibration could not be computed, so it cannot be "
                  "combined with the others");
    }
    posteriors.push_back(log.own.posterior);
    result.logs.push_back(std::move(log));
  }
  result.fused = estimation::FuseCalibrationPosteriors(posteriors);
  ConcludeShared(result.fused, &result);
  GiveBothWheelsTheSharedRadius(problem, &result.calibration);
  for (size_t i = 0; i < datasets.size(); ++i) {
    LogCalibration& log = result.logs[i];
    log.at_shared =
        SolveAtShared(datasets[i], problem, result.calibration.value, options.calibration);
    // Its warnings cover the trajectory written for it, and its fixed-block test says where its
    // data would move the shared calibration (Eq. C7).
    for (const std::string& w : log.at_shared.warnings) {
      result.warnings.push_back("log " + log.name + " at the shared calibration: " + w);
    }
  }
  result.repeatability = Repeatability(result.logs, posteriors, options.min_agreement_p_value);
  bool all_agree = true;
  for (const BlockRepeatability& r : result.repeatability) {
    if (!r.agree) result.warnings.push_back(r.finding);
    all_agree = all_agree && r.agree;
  }
  if (!all_agree) {
    result.warnings.push_back(
        "the shared calibration assumes one value of every block; where the logs differ (above) "
        "it is biased, also in the blocks correlated with the differing one: calibrate those "
        "logs apart");
  }
  result.seconds_total =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

std::vector<RepeatabilityRow> RepeatabilityRows(const MultiLogCalibrationResult& result) {
  std::vector<RepeatabilityRow> rows;
  for (const BlockRepeatability& r : result.repeatability) {
    const sensors::CalibrationBlockInfo& info = sensors::CalibrationBlock(r.agreement.id);
    const double* shared = info.const_values(result.calibration.value);
    // Direction k of the block among `blocks` (values, covariance): a rotation's value is its
    // rotation vector from the shared rotation, another block's its value.
    const auto entry = [&](const std::string& log,
                           const std::vector<estimation::EstimatedBlock>& blocks,
                           const estimation::BlockCovariance& covariance, const double* values,
                           int k) -> std::optional<RepeatabilityEntry> {
      for (size_t b = 0; b < blocks.size(); ++b) {
        if (blocks[b].id != info.id) continue;
        const double value = info.manifold == sensors::BlockManifold::kRightQuaternion
                                 ? estimation::BlockMinus(blocks[b], values, shared)(k)
                                 : values[k];
        const int row = covariance.offsets[b] + k;
        return RepeatabilityEntry{log, value * info.display_scale,
                                  std::sqrt(covariance.matrix(row, row)) * info.display_scale};
      }
      return std::nullopt;
    };
    for (int k = 0; k < info.tangent_size; ++k) {
      RepeatabilityRow row{&r, info.key, info.direction_names[k], info.display_unit, {}, {}};
      for (size_t i : r.agreement.logs) {
        const estimation::CalibrationPosterior& p = result.logs[i].own.posterior;
        if (auto e = entry(result.logs[i].name, p.blocks, p.Reported(), info.const_values(p.solved),
                           k)) {
          row.logs.push_back(*e);
        }
      }
      // The shared value is the reported one, after holding: its sigma is the reported one
      // (Eq. C2), not the fused covariance's from before.
      row.shared = *entry("shared", result.fused.blocks, result.fused.covariance, shared, k);
      for (size_t b = 0; b < result.fused.blocks.size(); ++b) {
        if (result.fused.blocks[b].id == info.id && b < result.observability.sigma.size()) {
          row.shared.sigma = result.observability.sigma[b](k) * info.display_scale;
        }
      }
      rows.push_back(row);
    }
  }
  return rows;
}

std::string RepeatabilityCsv(const MultiLogCalibrationResult& result) {
  std::ostringstream csv;
  csv << "block,direction,unit,log,value,sigma,chi_square,degrees_of_freedom,p_value,agree\n";
  csv << std::setprecision(10);
  for (const RepeatabilityRow& row : RepeatabilityRows(result)) {
    std::vector<RepeatabilityEntry> entries = row.logs;
    entries.push_back(row.shared);
    for (const RepeatabilityEntry& e : entries) {
      csv << row.key << ',' << row.direction << ',' << row.unit << ',' << CsvText(e.log) << ','
          << e.value << ',' << e.sigma << ',' << row.block->agreement.chi_square << ','
          << row.block->agreement.degrees_of_freedom << ',' << row.block->agreement.p_value << ','
          << (row.block->agree ? "yes" : "no") << '\n';
    }
  }
  return csv.str();
}

void WriteMultiLogResult(const std::string& directory, const MultiLogCalibrationResult& result,
                         const io::RunStatus* status) {
  io::StagedDirectory out(directory, io::OutputKind::kResult);
  io::WriteCalibrationYaml(out.File("calibration.yaml"), result.calibration);
  io::WriteFileAtomically(out.File("repeatability.csv"), RepeatabilityCsv(result));
  io::WriteFileAtomically(out.File("report.html"), MultiLogReportHtml(result));
  io::WriteWarningsFile(out.File("warnings.txt"), result.warnings);
  for (const LogCalibration& log : result.logs) {
    const std::string log_directory = out.File("logs/" + log.name);
    std::filesystem::create_directories(log_directory);
    io::WriteTumTrajectory(log_directory + "/trajectory.tum", log.at_shared.trajectory);
    WriteCalibrationResult(log_directory + "/own", log.own);
  }
  if (status != nullptr) io::WriteRunStatus(out.File("status.yaml"), *status);
  out.Commit();
}

std::string FormatMultiLogSummary(const MultiLogCalibrationResult& result) {
  std::ostringstream out;
  out << "shared calibration of " << result.logs.size() << " logs:\n"
      << FormatCalibrationValues(result.calibration);
  out << "repeatability (per block: do the logs share one value? chi-square test, flagged below p "
      << std::setprecision(2)
      << (result.repeatability.empty() ? 0.0 : result.repeatability.front().p_threshold) << "):\n";
  for (const BlockRepeatability& r : result.repeatability) {
    out << "  " << std::left << std::setw(28) << r.name << std::right << " chi-square "
        << std::setw(7) << FormatFixed(r.agreement.chi_square, 1) << " / "
        << r.agreement.degrees_of_freedom << " dof, p " << std::setprecision(3)
        << r.agreement.p_value << (r.agree ? "  agree" : "  DISAGREE") << '\n';
  }
  for (const LogCalibration& log : result.logs) {
    out << "log " << log.name << ": " << log.own.trajectory.size() << " keyframes, "
        << FormatFixed(log.own.seconds_total + log.at_shared.seconds_total, 1) << " s\n";
  }
  out << FormatFixed(result.seconds_total, 1) << " s in all\n";
  for (const std::string& warning : result.warnings) out << "warning: " << warning << '\n';
  return out.str();
}

}  // namespace pipeline
}  // namespace autocal
