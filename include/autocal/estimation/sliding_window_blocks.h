#pragma once

// Where each calibration block (sensors/calibration_blocks.h) lives in the window's options:
// its estimate switch and its prior sigma. The window keeps one switch for both radii and one
// for the vehicle frame's two blocks, and one sigma for both radii, so blocks may share them.

#include "autocal/estimation/sliding_window_options.h"
#include "autocal/sensors/calibration_blocks.h"

namespace autocal {
namespace estimation {

struct SlidingWindowBlockSetting {
  bool* estimate;
  double* prior_sigma;  // the prior's unit: degrees for a rotation
};

// Throws autocal::Error for a block the window does not support (WindowSupports).
SlidingWindowBlockSetting BlockSettingOf(sensors::CalibrationBlockId id,
                                         SlidingWindowEstimatedBlocks* estimate,
                                         SlidingWindowCalibrationPrior* prior);

// Block `id`'s prior sigma per tangent axis (degrees for a rotation, else the block's SI unit):
// `prior.axis_sigmas` where it holds the block, else the block's one sigma on every axis.
// Throws as BlockSettingOf.
Eigen::VectorXd PriorSigmasOf(sensors::CalibrationBlockId id,
                              const SlidingWindowCalibrationPrior& prior);

// Whether the window has a setting for block `id`: not yet for the blocks of the wheel forms
// linear_speeds and speed_yaw_rate (speed scales, odometry speed scale, effective track), nor
// the wheel and GNSS time offsets.
bool WindowSupports(sensors::CalibrationBlockId id);

// Whether the window estimates block `id` (false for a block it does not support).
bool Estimated(sensors::CalibrationBlockId id, const SlidingWindowEstimatedBlocks& estimate);

}  // namespace estimation
}  // namespace autocal
