#pragma once

// What the offline calibration's rules make of the sliding window's final result
// (docs/sliding_window.md, "Streaming a dataset" and "Fixed blocks"): its sigmas widened where
// the estimate's steps scatter, the directions the stream left at the prior, the plausibility
// of the rest, and the fixed blocks the stream contradicts.

#include <string>
#include <vector>

#include "autocal/estimation/increment_scatter.h"
#include "autocal/estimation/sliding_window.h"
#include "autocal/io/calibration_yaml.h"
#include "autocal/io/dataset.h"
#include "autocal/io/problem_yaml.h"

namespace autocal {
namespace pipeline {

// Eq. W9 on the window's final covariance (the last of `checkpoints`): the directions whose
// steps between the checkpoints scatter beyond chance at `significance` widened by that
// scatter, up to the window's prior sigma, with one warning naming the direction widened most
// and *file's residuals.window.step_scatter_ratio (the largest ratio of the steps' sigma to the
// predicted one over the directions tested). Fewer than two checkpoints: the covariance as
// it is.
estimation::CalibrationCovariance WidenedForSteps(
    const estimation::SlidingWindowOptions& window_options,
    const std::vector<estimation::CalibrationCheckpoint>& checkpoints, double significance,
    io::CalibrationFile* file, std::vector<std::string>* warnings);

// Observability per direction by the offline calibration's rule (docs/calibration.md,
// "Observability and uncertainty", Eqs. C1-C2) on the window's final covariance as widened
// (WidenedForSteps): a direction the stream left near the window's prior (posterior sigma above
// max_posterior_to_prior_sigma of the window's prior sigma, above max_kept_sigma_to_limit times its
// limit, or zero: the covariance's pseudo-inverse drops an unobservable one) is held at the prior's
// centre, and the others are conditioned on it. Moves *value (Eq. C1), fills *uncertainty (Eq. C2);
// returns whether any direction was held. Throws autocal::Error (RequirePlausible) when a
// direction the stream informs ends more than 5 prior sigmas from the prior; unlike the
// offline calibration, which judges by its widened covariance (Eq. C8), by the `solved` one:
// a drive that pulls an estimate far from a misstated prior scatters the window's steps too
// (Eq. W9 reads a misstated prior as scatter), and widened it would no longer be judged.
bool HoldWhatTheStreamLeft(const io::Dataset& dataset, const io::Problem& problem,
                           estimation::SlidingWindowOptions window_options, bool use_wheel,
                           bool use_gnss, const estimation::CalibrationCovariance& solved,
                           const estimation::CalibrationCovariance& widened,
                           sensors::Calibration* value, io::CalibrationUncertainty* uncertainty,
                           std::vector<std::string>* warnings);

// Eq. C7 over the whole stream (SlidingWindowEstimator::FixedDirectionsTheStreamMoves), with
// the offline calibration's priors and threshold.
void WarnOfFixedDirectionsTheStreamMoves(const io::Dataset& dataset, const io::Problem& problem,
                                         bool use_wheel, bool use_gnss,
                                         estimation::SlidingWindowEstimator* estimator,
                                         std::vector<std::string>* warnings);

}  // namespace pipeline
}  // namespace autocal
