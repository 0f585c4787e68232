#pragma once

// The online estimator's start without the LiDAR (docs/sliding_window.md, "Without the
// LiDAR"): the keyframe period, which takes the sweeps' place, and the initial state from GNSS
// and the IMU, which takes the LiDAR-IMU initializer's.

#include <cstdint>
#include <string>
#include <vector>

#include "autocal/estimation/keyframe.h"
#include "autocal/estimation/sliding_window_options.h"
#include "autocal/io/dataset.h"
#include "autocal/io/problem_yaml.h"
#include "autocal/pipeline/online_estimation.h"
#include "calibration_steps.h"

namespace autocal {
namespace pipeline {

// The period of the keyframes (ns): options.keyframe_period_without_lidar_s when set, else the
// median interval of the GNSS fixes clamped to [0.05, 0.5] s, so that a keyframe interval
// holds about one fix. Throws autocal::Error naming gnss.csv when fewer than two fixes leave
// no interval to measure.
int64_t KeyframePeriodWithoutLidar(const io::Dataset& dataset,
                                   const OnlineEstimationOptions& options);

// The log as the window without the LiDAR reads it (docs/sliding_window.md, "Clocks and mount
// without the LiDAR"): the IMU mount and the wheel and GNSS clock offsets from the data as the
// offline calibration initializes them (InitializeMountAndClocks: a nominal mount that is no
// guess replaced by the data's, its roll and pitch centred on gravity's (Eq. C4); an offset
// the problem estimates from the cross-correlation, else the nominal one), then the wheel and
// GNSS stamps moved onto the IMU clock
// (t_imu = t + offset) and the offsets in the copy's nominal calibration zeroed. The window
// holds the offsets: *problem has them fixed, *applied keeps them for the result, and
// *warnings says so.
io::Dataset OnImuClock(const io::Dataset& dataset, io::Problem* problem,
                       sensors::Calibration* applied, std::vector<std::string>* warnings);

// Keyframes every period_ns over the first options.initialization_duration_s of the span the
// IMU and the fixes share, placed on the GNSS track and refined with the IMU and the wheels
// (estimation::KeyframesFromGnssAndImu, the offline calibration's start without the LiDAR) at
// the nominal calibration. Returns the first, in the ENU frame at the first fix; sets
// *window_options as SetGnssStart (window_settings.h), which may add a warning to *warnings.
// Throws autocal::Error when that span holds fewer than two keyframes, or as
// KeyframesFromGnssAndImu.
estimation::Keyframe StartWithoutLidar(const io::Dataset& dataset, const io::Problem& problem,
                                       const OnlineEstimationOptions& options,
                                       const TimingLimits& timing, int64_t period_ns,
                                       bool use_wheel,
                                       estimation::SlidingWindowOptions* window_options,
                                       std::vector<std::string>* warnings);

}  // namespace pipeline
}  // namespace autocal
