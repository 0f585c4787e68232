#pragma once

// The sliding window's settings for a problem and its covariance in the calibration file:
// where the online estimation meets the window's options, in terms of the block table
// (sensors/calibration_blocks.h).

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "autocal/estimation/gnss_inertial_keyframes.h"
#include "autocal/estimation/sliding_window.h"
#include "autocal/io/calibration_yaml.h"
#include "autocal/io/dataset.h"
#include "autocal/io/problem_yaml.h"
#include "autocal/pipeline/online_estimation.h"
#include "autocal/sensors/gnss_enu.h"

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

// A start from GNSS: W is the ENU frame at the first fix (enu), and the first keyframe comes
// from the GNSS-inertial solve over the first seconds. The initial state's covariance is that
// solve's (start_covariance: a slow platform's yaw is worth degrees, a car's tenths, and on a
// road without turns the tilt trades against the accelerometer bias, held only by its prior)
// plus the initial sigmas, which stand for what the solve's model leaves out (options' position
// and accelerometer-bias sigmas for a GNSS start); those alone when the solve left a direction
// undetermined (first_covariance empty). The window's fixes take the std scale the solve's fixes
// showed (Eq. N2) until the window's own rows judge it; *warnings gets Eq. N2's warning when that
// scale is not one.
void SetGnssStart(const sensors::EnuConverter& enu, const estimation::GnssInertialKeyframes& start,
                  const OnlineEstimationOptions& options,
                  estimation::SlidingWindowOptions* window_options,
                  std::vector<std::string>* warnings);

// Sigmas of the estimated blocks from the window's covariance, into the calibration file.
void FillWindowUncertainty(const estimation::CalibrationCovariance& covariance,
                           io::CalibrationUncertainty* uncertainty);

}  // namespace pipeline
}  // namespace autocal
