#pragma once

// The median of values added one at a time (the upper one for an even count), in O(log n) per
// value: the smaller half in a max-heap, the larger in a min-heap, which holds the extra value
// of an odd count.

#include <cstddef>
#include <functional>
#include <queue>
#include <vector>

namespace autocal {

class RunningMedian {
 public:
  void Add(double value) {
    if (!upper_.empty() && value < upper_.top()) {
      lower_.push(value);
    } else {
      upper_.push(value);
    }
    if (lower_.size() > upper_.size()) {
      upper_.push(lower_.top());
      lower_.pop();
    } else if (upper_.size() > lower_.size() + 1) {
      lower_.push(upper_.top());
      upper_.pop();
    }
  }
  size_t size() const { return lower_.size() + upper_.size(); }
  // Not empty.
  double Median() const { return upper_.top(); }

 private:
  std::priority_queue<double> lower_;
  std::priority_queue<double, std::vector<double>, std::greater<double>> upper_;
};

}  // namespace autocal
