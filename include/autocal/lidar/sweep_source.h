#pragma once

// A log's sweeps in stamp order, read when asked for. A consumer that passes over a log
// (the odometry) then holds one stretch of it at a time: a 10-minute log's sweeps are
// gigabytes, its odometry a few megabytes.

#include <cstddef>
#include <vector>

#include "autocal/lidar/point_cloud.h"

namespace autocal {
namespace lidar {

class SweepSource {
 public:
  virtual ~SweepSource() = default;
  virtual size_t size() const = 0;
  // Sweep k (k < size()); the reference stays valid until the next call. Throws
  // autocal::Error (or a ParseError naming the file) when it cannot be read.
  virtual const LidarSweep& Sweep(size_t k) = 0;
};

// The sweeps of a vector that outlives it.
class SweepVector final : public SweepSource {
 public:
  explicit SweepVector(const std::vector<LidarSweep>& sweeps) : sweeps_(sweeps) {}
  size_t size() const override { return sweeps_.size(); }
  const LidarSweep& Sweep(size_t k) override { return sweeps_[k]; }

 private:
  const std::vector<LidarSweep>& sweeps_;
};

// The first `count` sweeps of another source that outlives it.
class SweepPrefix final : public SweepSource {
 public:
  SweepPrefix(SweepSource* source, size_t count)
      : source_(source), count_(count < source->size() ? count : source->size()) {}
  size_t size() const override { return count_; }
  const LidarSweep& Sweep(size_t k) override { return source_->Sweep(k); }

 private:
  SweepSource* source_;
  size_t count_;
};

}  // namespace lidar
}  // namespace autocal
