#pragma once

// The Cramer-Rao bound of a calibration on a simulated log (docs/evaluation.md, "Information
// bound"): the covariance of the estimated blocks from the information J^T J of the final
// problem evaluated at the truth instead of at the estimate. An efficient estimator's sigma
// matches it; its errors over many logs scatter as it says.
//
// TruthSetter gives pipeline::OfflineCalibrationOptions::set_to_truth for a log with ground
// truth (groundtruth/trajectory.csv and groundtruth/calibration.yaml). The truth is put into
// the estimate's world frame by the 4-DoF alignment (yaw, translation) of the keyframe
// positions onto it, the only freedom between the two frames. The keyframes' biases are the
// truth's where the log has groundtruth/imu_bias.csv (linear between its samples), else they
// stay at their estimate: they enter the Jacobians at second order, but the residuals at the
// truth, which the error budget splits, at first.

#include "autocal/estimation/keyframe.h"
#include "autocal/io/dataset.h"
#include "autocal/sensors/calibration.h"

namespace autocal {
namespace evaluation {

// Sets every keyframe within the truth's span (interpolated where no sample has its stamp) and
// the whole calibration to the truth of `dataset`. An empty function when the dataset has no
// ground truth trajectory or calibration. The setter throws autocal::Error when fewer than two
// keyframes lie within the truth.
estimation::StateSetter TruthSetter(const io::Dataset& dataset);

}  // namespace evaluation
}  // namespace autocal
