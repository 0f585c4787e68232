#include "online_judgement.h"

#include <algorithm>

#include "autocal/common/error.h"
#include "autocal/estimation/calibration_observability.h"
#include "autocal/estimation/sliding_window_blocks.h"
#include "autocal/pipeline/offline_calibration.h"
#include "autocal/sensors/calibration_blocks.h"
#include "calibration_steps.h"
#include "problem_blocks.h"

namespace autocal {
namespace pipeline {

bool HoldWhatTheStreamLeft(const io::Dataset& dataset, const io::Problem& problem,
                           estimation::SlidingWindowOptions window_options, bool use_wheel,
                           bool use_gnss, const estimation::CalibrationCovariance& covariance,
                           sensors::Calibration* value, io::CalibrationUncertainty* uncertainty,
                           std::vector<std::string>* warnings) {
  sensors::Calibration scratch = dataset.sensors.nominal_calibration;
  const std::vector<estimation::EstimatedBlock> limits = EstimatedBlocks(
      problem, dataset.sensors, OfflineCalibrationOptions(), use_wheel, use_gnss, &scratch);
  const sensors::Calibration prior_mean =
      window_options.calibration_prior.mean.value_or(dataset.sensors.nominal_calibration);
  std::vector<estimation::EstimatedBlock> blocks;
  std::vector<int> rows;  // the covariance's rows of the blocks, in order
  for (size_t b = 0; b < covariance.names.size(); ++b) {
    const sensors::CalibrationBlockInfo* info = sensors::FindCalibrationBlock(covariance.names[b]);
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
    block.prior_sigma = estimation::PriorSigmasOf(info->id, window_options.calibration_prior) *
                        FileToTangent(*info);
    blocks.push_back(block);
    for (int k = 0; k < info->tangent_size; ++k) rows.push_back(covariance.offsets[b] + k);
  }
  estimation::BlockCovariance held;
  held.ok = true;
  const int n = static_cast<int>(rows.size());
  held.matrix.resize(n, n);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) held.matrix(i, j) = covariance.covariance(rows[i], rows[j]);
  }
  int row = 0;
  for (const estimation::EstimatedBlock& block : blocks) {
    held.offsets.push_back(row);
    for (int k = 0; k < block.size; ++k, ++row) {
      if (held.matrix(row, row) > 0.0) continue;
      // Dropped by the pseudo-inverse: the data left it at its prior.
      held.matrix.row(row).setZero();
      held.matrix.col(row).setZero();
      held.matrix(row, row) = block.prior_sigma(k) * block.prior_sigma(k);
    }
  }
  // The offline calibration's plausibility rule (docs/calibration.md): nothing is written.
  RequirePlausible(dataset, OfflineCalibrationOptions(), blocks, held);
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
      warnings->push_back(FixedDirectionWarning(moved));
    }
  } catch (const Error& e) {
    warnings->push_back(e.what());
  }
}

}  // namespace pipeline
}  // namespace autocal
