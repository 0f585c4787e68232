#pragma once

// The calibration blocks a problem estimates (docs/calibration.md, "Observability and
// uncertainty"): each with its prior (the problem's sigma in prior mode, else the dataset's
// stated nominal uncertainty, else the options' weak default) and its observability limits;
// and the result's uncertainty section from the observability analysis of those blocks.

#include <vector>

#include "autocal/io/calibration_yaml.h"
#include "autocal/io/dataset.h"
#include "autocal/io/problem_yaml.h"
#include "autocal/pipeline/offline_calibration.h"
#include "autocal/sensors/calibration.h"
#include "calibration_blocks.h"

namespace autocal {
namespace pipeline {

// The blocks of `problem` that are estimated, their data pointing into `calibration`; the
// wheel blocks only with use_wheel, the lever arm only with use_gnss.
std::vector<CalibrationBlock> EstimatedBlocks(const io::Problem& problem,
                                              const io::SensorsConfig& sensors,
                                              const OfflineCalibrationOptions& options,
                                              bool use_wheel, bool use_gnss,
                                              sensors::Calibration* calibration);

// Sigma and observability flags of every block in `uncertainty`.
void FillUncertainty(const std::vector<CalibrationBlock>& blocks, const BlockObservability& obs,
                     io::CalibrationUncertainty* uncertainty);

}  // namespace pipeline
}  // namespace autocal
