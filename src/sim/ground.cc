#include "autocal/sim/ground.h"

#include <cmath>
#include <string>
#include <utility>

#include "autocal/common/error.h"

namespace autocal {
namespace sim {

GradeProfile::GradeProfile(std::vector<Transition> transitions)
    : transitions_(std::move(transitions)) {
  first_grade_ = transitions_.empty() ? 0.0 : transitions_.front().grade_before;
  for (size_t i = 0; i < transitions_.size(); ++i) {
    const Transition& tr = transitions_[i];
    if (!(tr.u_end > tr.u_begin) || !std::isfinite(tr.u_begin) || !std::isfinite(tr.u_end)) {
      throw Error("simulated ground: grade transition " + std::to_string(i) +
                  " has an empty or non-finite interval");
    }
    if (i > 0 && (tr.u_begin < transitions_[i - 1].u_end ||
                  tr.grade_before != transitions_[i - 1].grade_after)) {
      throw Error("simulated ground: grade transition " + std::to_string(i) +
                  " overlaps the previous one or does not continue its grade");
    }
  }
  if (transitions_.empty()) return;
  // Heights relative to the start of the first transition, then shifted so that h(0) = 0.
  height_before_.resize(transitions_.size());
  height_after_.resize(transitions_.size());
  double height = 0.0;
  double u = transitions_.front().u_begin;
  for (size_t i = 0; i < transitions_.size(); ++i) {
    const Transition& tr = transitions_[i];
    height += tr.grade_before * (tr.u_begin - u);
    height_before_[i] = height;
    // The smooth step integrates to 1/2: mean grade across the transition.
    height += 0.5 * (tr.grade_before + tr.grade_after) * (tr.u_end - tr.u_begin);
    height_after_[i] = height;
    u = tr.u_end;
  }
  const double h0 = Height(0.0);
  for (size_t i = 0; i < transitions_.size(); ++i) {
    height_before_[i] -= h0;
    height_after_[i] -= h0;
  }
}

}  // namespace sim
}  // namespace autocal
