#pragma once

// Where each calibration block (sensors/calibration_blocks.h) lives in the two file structs
// that hold one entry per block: a problem file's settings (ProblemCalibration) and a
// calibration file's uncertainty (CalibrationUncertainty). Code that goes over the blocks reads
// and writes them through these, in the block table's order, instead of naming each field.
// Values are in file units: degrees for a rotation, else the block's SI unit; one per tangent
// direction.

#include <Eigen/Core>
#include <optional>
#include <vector>

#include "autocal/io/calibration_yaml.h"
#include "autocal/io/problem_yaml.h"
#include "autocal/sensors/calibration_blocks.h"

namespace autocal {
namespace io {

// Block `id`'s mode and prior sigma in a problem (prior_sigma is zero unless mode is kPrior).
struct BlockModeAndSigma {
  BlockMode mode = BlockMode::kEstimate;
  Eigen::VectorXd prior_sigma;
};
BlockModeAndSigma BlockSettingIn(const ProblemCalibration& problem, sensors::CalibrationBlockId id);
void SetBlockSetting(sensors::CalibrationBlockId id, const BlockModeAndSigma& setting,
                     ProblemCalibration* problem);
// The block's name in a problem file: "T_I_L rotation", "wheel_radius_left_m", "p_I_A_m".
const char* ProblemKey(sensors::CalibrationBlockId id);

// Block `id`'s part of an uncertainty: its sigma when the file states one, and its observable
// flags: empty (observable), one for the whole block, or one per direction.
struct BlockUncertainty {
  std::optional<Eigen::VectorXd> sigma;
  std::vector<bool> observable;
};
BlockUncertainty UncertaintyIn(const CalibrationUncertainty& uncertainty,
                               sensors::CalibrationBlockId id);
// Sets block `id`'s sigma, and its flags (one per direction) when `observable` is given. A
// pose's six flags are written when either half gets flags; the other half's are then false
// while it has no sigma (a half the problem fixes is not estimated, so not observable).
void SetBlockUncertainty(sensors::CalibrationBlockId id, const Eigen::VectorXd& sigma,
                         const std::vector<bool>* observable, CalibrationUncertainty* uncertainty);

}  // namespace io
}  // namespace autocal
