#include "online_judgement.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "autocal/common/error.h"
#include "autocal/common/format.h"
#include "autocal/estimation/calibration_observability.h"
#include "autocal/estimation/sliding_window_blocks.h"
#include "autocal/pipeline/offline_calibration.h"
#include "autocal/sensors/calibration_blocks.h"
#include "calibration_steps.h"
#include "problem_blocks.h"

namespace autocal {
namespace pipeline {

namespace {

// The window's prior sigma of a block, per direction in its tangent's units.
Eigen::VectorXd WindowPriorSigma(const sensors::CalibrationBlockInfo& info,
                                 const estimation::SlidingWindowOptions& window_options) {
  return estimation::PriorSigmasOf(info.id, window_options.calibration_prior) * FileToTangent(info);
}

// The window's prior variance of each row of `covariance` (infinite where it has none).
Eigen::VectorXd PriorVariances(const estimation::CalibrationCovariance& covariance,
                               const estimation::SlidingWindowOptions& window_options) {
  Eigen::VectorXd out = Eigen::VectorXd::Constant(covariance.covariance.rows(),
                                                  std::numeric_limits<double>::infinity());
  for (size_t b = 0; b < covariance.names.size(); ++b) {
    const sensors::CalibrationBlockInfo* info = sensors::FindCalibrationBlock(covariance.names[b]);
    if (info == nullptr) continue;
    out.segment(covariance.offsets[b], info->tangent_size) =
        WindowPriorSigma(*info, window_options).cwiseAbs2();
  }
  return out;
}

// The name of row `row` of `covariance`'s block `key`.
std::string DirectionName(const estimation::CalibrationCovariance& covariance,
                          const std::string& key, int row) {
  const sensors::CalibrationBlockInfo& info = *sensors::FindCalibrationBlock(key);
  for (size_t b = 0; b < covariance.names.size(); ++b) {
    if (covariance.names[b] == key) return info.direction_names[row - covariance.offsets[b]];
  }
  return key;
}

// `covariance`'s rows of `blocks`, a direction the pseudo-inverse dropped (no information: the
// data left it at its prior) at its prior's variance.
estimation::BlockCovariance BlockCovarianceOf(
    const estimation::CalibrationCovariance& covariance, const std::vector<int>& rows,
    const std::vector<estimation::EstimatedBlock>& blocks) {
  estimation::BlockCovariance out;
  out.ok = true;
  const int n = static_cast<int>(rows.size());
  out.matrix.resize(n, n);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) out.matrix(i, j) = covariance.covariance(rows[i], rows[j]);
  }
  int row = 0;
  for (const estimation::EstimatedBlock& block : blocks) {
    out.offsets.push_back(row);
    for (int k = 0; k < block.size; ++k, ++row) {
      if (out.matrix(row, row) > 0.0) continue;
      out.matrix.row(row).setZero();
      out.matrix.col(row).setZero();
      out.matrix(row, row) = block.prior_sigma(k) * block.prior_sigma(k);
    }
  }
  return out;
}

}  // namespace

estimation::CalibrationCovariance WidenedForSteps(
    const estimation::SlidingWindowOptions& window_options,
    const std::vector<estimation::CalibrationCheckpoint>& checkpoints, double significance,
    io::CalibrationFile* file, std::vector<std::string>* warnings) {
  const estimation::CalibrationCovariance& covariance = checkpoints.back().covariance;
  const estimation::IncrementScatter scatter =
      estimation::ScatterOfIncrements(checkpoints, significance);
  if (scatter.directions.empty()) return covariance;
  double largest = 0.0;
  for (const estimation::IncrementScatter::Direction& d : scatter.directions) {
    largest = std::max(largest, std::sqrt(d.ratio));
  }
  file->residuals["window"]["step_scatter_ratio"] = largest;
  std::vector<estimation::WidenedDirection> widened;
  const estimation::CalibrationCovariance out = estimation::WidenedForIncrements(
      covariance, scatter, PriorVariances(covariance, window_options), &widened);
  if (!widened.empty()) {
    const estimation::IncrementScatter::Direction& most = widened.front().direction;
    warnings->push_back(
        "the window's estimate of the " + DirectionName(covariance, most.block, most.row) +
        " moved over " + std::to_string(most.steps) + " spans of the stream " +
        FormatFixed(std::sqrt(most.ratio), 1) +
        " times as widely as its covariance says (errors that last for stretches of the drive, "
        "or noise larger than stated); its sigma is widened " +
        FormatFixed(widened.front().sigma_factor, 2) + " times (" + std::to_string(widened.size()) +
        " direction(s) widened, Eq. W9)");
  }
  return out;
}

bool HoldWhatTheStreamLeft(const io::Dataset& dataset, const io::Problem& problem,
                           estimation::SlidingWindowOptions window_options, bool use_wheel,
                           bool use_gnss, const estimation::CalibrationCovariance& solved,
                           const estimation::CalibrationCovariance& widened,
                           sensors::Calibration* value, io::CalibrationUncertainty* uncertainty,
                           std::vector<std::string>* warnings) {
  if (widened.names != solved.names || widened.offsets != solved.offsets ||
      widened.covariance.rows() != solved.covariance.rows()) {
    throw Error("HoldWhatTheStreamLeft: the widened covariance's blocks are not the solved one's");
  }
  sensors::Calibration scratch = dataset.sensors.nominal_calibration;
  const std::vector<estimation::EstimatedBlock> limits = EstimatedBlocks(
      problem, dataset.sensors, OfflineCalibrationOptions(), use_wheel, use_gnss, &scratch);
  const sensors::Calibration prior_mean =
      window_options.calibration_prior.mean.value_or(dataset.sensors.nominal_calibration);
  std::vector<estimation::EstimatedBlock> blocks;
  std::vector<int> rows;  // the covariances' rows of the blocks, in order
  for (size_t b = 0; b < solved.names.size(); ++b) {
    const sensors::CalibrationBlockInfo* info = sensors::FindCalibrationBlock(solved.names[b]);
    if (info == nullptr) continue;
    const auto limit =
        std::find_if(limits.begin(), limits.end(),
                     [info](const estimation::EstimatedBlock& e) { return e.id == info->id; });
    if (limit == limits.end()) continue;
    estimation::EstimatedBlock block = *limit;
    block.data = info->values(value);
    block.prior =
        Eigen::Map<const Eigen::VectorXd>(info->const_values(prior_mean), info->ambient_size);
    block.prior_source = "the window's prior centre";
    block.prior_sigma = WindowPriorSigma(*info, window_options);
    blocks.push_back(block);
    for (int k = 0; k < info->tangent_size; ++k) rows.push_back(solved.offsets[b] + k);
  }
  // The offline calibration's plausibility rule (docs/calibration.md): nothing is written. It
  // asks where the data took a direction they inform, which the steps' scatter does not
  // change (a drive that pulls an estimate far from a misstated prior scatters its steps).
  RequirePlausible(dataset, OfflineCalibrationOptions(), blocks,
                   BlockCovarianceOf(solved, rows, blocks));
  const estimation::BlockCovariance held = BlockCovarianceOf(widened, rows, blocks);
  const estimation::BlockObservability observability =
      estimation::HoldUnobservableDirections(blocks, held);
  FillUncertainty(blocks, observability, uncertainty);
  warnings->insert(warnings->end(), observability.warnings.begin(), observability.warnings.end());
  return estimation::AnyHeld(observability);
}

void WarnOfFixedDirectionsTheStreamMoves(const io::Dataset& dataset, const io::Problem& problem,
                                         bool use_wheel, bool use_gnss,
                                         estimation::SlidingWindowEstimator* estimator,
                                         std::vector<std::string>* warnings) {
  const OfflineCalibrationOptions offline;
  sensors::Calibration scratch = dataset.sensors.nominal_calibration;
  try {
    for (const estimation::FixedDirectionMove& moved : estimator->FixedDirectionsTheStreamMoves(
             FixedBlocks(problem, dataset.sensors, offline, use_wheel, use_gnss, &scratch),
             offline.max_fixed_block_step_sigmas)) {
      warnings->push_back(moved.text + offline.fixed_block_advice);
    }
  } catch (const Error& e) {
    warnings->push_back(e.what());
  }
}

}  // namespace pipeline
}  // namespace autocal
