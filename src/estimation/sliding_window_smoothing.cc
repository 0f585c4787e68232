// The sliding window's smoother (docs/sliding_window.md, "Smoothing"): the conditional kept at
// every marginalization (Eq. M4) and the backward pass over them.
#include <algorithm>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/estimation/sliding_window.h"
#include "estimation/sliding_window_internal.h"

namespace autocal {
namespace estimation {

using internal::StateBlocks;

// The conditional of the keyframe being marginalized (the window's oldest), each of its kept
// blocks named by keyframe id and state block, or as a calibration block.
void SlidingWindowEstimator::Impl::RecordSmoothingStep(MarginalConditional conditional) {
  SmoothingStep step;
  step.keyframe_id = window_.front()->id;
  step.conditional = std::move(conditional);
  const auto index_in = [](const std::vector<double*>& list, const double* p) {
    return static_cast<int>(std::find(list.begin(), list.end(), p) - list.begin());
  };
  const std::vector<double*> oldest = StateBlocks(&window_.front()->state);
  for (const PriorBlock& b : step.conditional.marginalized_blocks()) {
    step.marginalized.push_back(index_in(oldest, b.values));
  }
  const std::vector<internal::CalibrationBlock> calibration =
      internal::CalibrationBlocks(&calibration_, options_.estimate);
  for (const PriorBlock& b : step.conditional.kept_blocks()) {
    SmoothingStep::BlockRef ref;
    if (std::any_of(calibration.begin(), calibration.end(),
                    [&b](const internal::CalibrationBlock& c) { return c.values == b.values; })) {
      ref.calibration = b.values;
    } else {
      for (const auto& kf : window_) {
        const int i = index_in(StateBlocks(&kf->state), b.values);
        if (i < 5) {
          ref.keyframe_id = kf->id;
          ref.state_block = i;
          break;
        }
      }
      if (ref.keyframe_id < 0) {
        throw Error(
            "SlidingWindowEstimator: a block the oldest keyframe is marginalized onto "
            "is neither a window keyframe's nor a calibration block");
      }
    }
    step.kept.push_back(ref);
  }
  smoothing_.push_back(std::move(step));
}

// The Rauch-Tung-Striebel pass: Eq. M4 backwards, at `calibration` (a conditional names the
// window's calibration blocks; the same block of `calibration` stands in for each).
std::vector<SlidingWindowState> SlidingWindowEstimator::Impl::SmoothedTrajectory(
    const sensors::Calibration& calibration) const {
  if (!options_.smoothing) {
    throw Error("SlidingWindowEstimator::SmoothedTrajectory needs SlidingWindowOptions::smoothing");
  }
  if (smoothing_.size() != marginalized_.size()) {
    throw Error("SlidingWindowEstimator: " + std::to_string(smoothing_.size()) +
                " smoothing steps for " + std::to_string(marginalized_.size()) +
                " marginalized keyframes");
  }
  std::vector<SlidingWindowState> out = Trajectory();
  sensors::Calibration given = calibration;
  // The window's blocks by address only (nothing is written through them).
  const std::vector<internal::CalibrationBlock> window_blocks = internal::CalibrationBlocks(
      const_cast<sensors::Calibration*>(&calibration_), options_.estimate);
  const std::vector<internal::CalibrationBlock> given_blocks =
      internal::CalibrationBlocks(&given, options_.estimate);
  const auto stand_in = [&](const double* window_block) -> const double* {
    for (size_t b = 0; b < window_blocks.size(); ++b) {
      if (window_blocks[b].values == window_block) return given_blocks[b].values;
    }
    throw Error("SlidingWindowEstimator: a smoothing step names an unknown calibration block");
  };
  std::unordered_map<int, size_t> index_of_id;
  for (size_t i = 0; i < smoothing_.size(); ++i) index_of_id[smoothing_[i].keyframe_id] = i;
  for (size_t j = 0; j < window_.size(); ++j) {
    index_of_id[window_[j]->id] = smoothing_.size() + j;
  }
  std::vector<const double*> kept;
  std::vector<double*> marginalized;
  for (size_t i = smoothing_.size(); i-- > 0;) {
    const SmoothingStep& step = smoothing_[i];
    kept.clear();
    for (const SmoothingStep::BlockRef& ref : step.kept) {
      kept.push_back(ref.keyframe_id < 0
                         ? stand_in(ref.calibration)
                         : StateBlocks(&out[index_of_id.at(ref.keyframe_id)])[ref.state_block]);
    }
    const std::vector<double*> blocks = StateBlocks(&out[i]);
    marginalized.clear();
    for (int b : step.marginalized) marginalized.push_back(blocks[b]);
    step.conditional.Apply(kept, marginalized);
  }
  return out;
}

}  // namespace estimation
}  // namespace autocal
