#pragma once

// The sliding window's settings for a problem and its covariance in the calibration file:
// where the online estimation meets the window's options, in terms of the block table
// (sensors/calibration_blocks.h).

#include "autocal/estimation/sliding_window.h"
#include "autocal/io/calibration_yaml.h"
#include "autocal/io/dataset.h"
#include "autocal/io/problem_yaml.h"
#include "autocal/pipeline/online_estimation.h"

namespace autocal {
namespace pipeline {

// The window options of a problem: what it estimates, its priors (centred at the dataset's
// nominal calibration), losses, residual points and solver; the rest from options.window.
// Throws autocal::Error for a shared wheel radius, a problem that fixes only one radius, a
// block the window cannot estimate (the wheel and GNSS clocks) that the problem estimates, or
// a nonzero nominal wheel or GNSS clock offset.
estimation::SlidingWindowOptions WindowOptions(const io::Dataset& dataset,
                                               const io::Problem& problem, bool use_wheel,
                                               bool use_gnss,
                                               const OnlineEstimationOptions& options);

// The window's planar-rotation rows (Eq. F27) when the problem asks for them with the wheels
// (use_wheel): calibration.roll_pitch_rate_sigma_rad_s, or, when "measured", the spread of the
// log's body rates at the keyframe period and the start's mount q_I_V (Eq. K15, the gyro
// averaged as the window's wheel rows average it). Zero: no rows.
double PlanarRotationSigma(const io::Dataset& dataset, const io::Problem& problem, bool use_wheel,
                           double keyframe_period_s, const Eigen::Quaterniond& q_I_V,
                           const estimation::WheelRowOptions& wheel_rows);

// Sigmas of the estimated blocks from the window's covariance, into the calibration file.
void FillWindowUncertainty(const estimation::CalibrationCovariance& covariance,
                           io::CalibrationUncertainty* uncertainty);

}  // namespace pipeline
}  // namespace autocal
