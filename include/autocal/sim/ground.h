#pragma once

// The simulated ground: a smooth height field z = A(x) + B(y) over the world plane, where A
// and B are road-grade profiles (piecewise constant grades joined by smooth-step
// transitions). Roads along x climb with A' and are banked by B', and the other way round for
// roads along y, so a drive gets pitch and roll from the road itself. Templated evaluation so
// the trajectory can differentiate through it.

#include <Eigen/Core>
#include <algorithm>
#include <vector>

#include "autocal/sim/smooth_step.h"

namespace autocal {
namespace sim {

// A 1D grade profile g(u) = dh/du: constant between transitions; across a transition
// [u_begin, u_end] the grade moves from grade_before to grade_after with a smooth step.
class GradeProfile {
 public:
  struct Transition {
    double u_begin = 0.0;
    double u_end = 1.0;
    double grade_before = 0.0;
    double grade_after = 0.0;
  };

  GradeProfile() = default;
  // Transitions must be sorted, non-overlapping and chain (grade_after of one equals
  // grade_before of the next); throws autocal::Error otherwise. h(0) = 0.
  explicit GradeProfile(std::vector<Transition> transitions);

  template <typename T>
  T Height(const T& u) const {
    const double u0 = ScalarValue(u);
    const int i = Locate(u0);
    if (i < 0) {
      if (transitions_.empty()) return T(0.0);
      return T(height_before_[0]) + T(first_grade_) * (u - T(transitions_[0].u_begin));
    }
    const Transition& tr = transitions_[i];
    const double width = tr.u_end - tr.u_begin;
    if (u0 >= tr.u_end) {
      return T(height_after_[i]) + T(tr.grade_after) * (u - T(tr.u_end));
    }
    const T x = (u - T(tr.u_begin)) / T(width);
    return T(height_before_[i]) + T(tr.grade_before) * (u - T(tr.u_begin)) +
           T((tr.grade_after - tr.grade_before) * width) * SmoothStepIntegral(x);
  }

  template <typename T>
  T Grade(const T& u) const {
    const double u0 = ScalarValue(u);
    const int i = Locate(u0);
    if (i < 0) return T(first_grade_);
    const Transition& tr = transitions_[i];
    if (u0 >= tr.u_end) return T(tr.grade_after);
    const T x = (u - T(tr.u_begin)) / T(tr.u_end - tr.u_begin);
    return T(tr.grade_before) + T(tr.grade_after - tr.grade_before) * SmoothStep(x);
  }

  const std::vector<Transition>& transitions() const { return transitions_; }

 private:
  // Index of the last transition with u_begin <= u, or -1 before the first one.
  int Locate(double u) const {
    const auto it =
        std::upper_bound(transitions_.begin(), transitions_.end(), u,
                         [](double value, const Transition& tr) { return value < tr.u_begin; });
    return static_cast<int>(it - transitions_.begin()) - 1;
  }

  std::vector<Transition> transitions_;
  std::vector<double> height_before_;  // h(u_begin) per transition
  std::vector<double> height_after_;   // h(u_end) per transition
  double first_grade_ = 0.0;
};

// z = A(x) + B(y), so that the ground passes through z = 0 at the world origin.
class GroundSurface {
 public:
  GroundSurface() = default;
  GroundSurface(GradeProfile along_x, GradeProfile along_y)
      : along_x_(std::move(along_x)), along_y_(std::move(along_y)) {}

  template <typename T>
  T Height(const T& x, const T& y) const {
    return along_x_.Height(x) + along_y_.Height(y);
  }
  // (dz/dx, dz/dy).
  template <typename T>
  Eigen::Matrix<T, 2, 1> Gradient(const T& x, const T& y) const {
    return Eigen::Matrix<T, 2, 1>(along_x_.Grade(x), along_y_.Grade(y));
  }

  const GradeProfile& along_x() const { return along_x_; }
  const GradeProfile& along_y() const { return along_y_; }

 private:
  GradeProfile along_x_;
  GradeProfile along_y_;
};

}  // namespace sim
}  // namespace autocal
