#include "keyframe_sweep_reader.h"

#include <algorithm>
#include <chrono>
#include <string>
#include <utility>

#include "autocal/common/error.h"
#include "autocal/common/parallel_for.h"

namespace autocal {
namespace pipeline {
namespace internal {

namespace {

// Sweeps read together: enough to keep every thread busy, few enough (about 1 MB each) that
// the stretch stays small against the reduced log.
constexpr size_t kStretchPerThread = 16;

}  // namespace

KeyframeSweepReader::KeyframeSweepReader(const io::Dataset& dataset, int stride,
                                         const estimation::PairingOptions& pairing, int num_threads,
                                         std::function<void(double)> progress)
    : dataset_(dataset),
      stride_(stride),
      pairing_(pairing),
      num_threads_(std::max(1, num_threads)),
      progress_(std::move(progress)) {
  if (stride < 1) throw Error("KeyframeSweepReader: the stride must be at least 1");
  const size_t count =
      (dataset.lidar_sweeps.size() + static_cast<size_t>(stride) - 1) / static_cast<size_t>(stride);
  selected_.resize(count);
  taken_.assign(count, false);
}

const lidar::LidarSweep& KeyframeSweepReader::Sweep(size_t k) {
  if (k >= size()) {
    throw Error("KeyframeSweepReader: sweep " + std::to_string(k) + " of " +
                std::to_string(size()));
  }
  if (k < first_ || k >= first_ + stretch_.size()) ReadStretch(k);
  return stretch_[k - first_];
}

void KeyframeSweepReader::ReadStretch(size_t first) {
  const auto start = std::chrono::steady_clock::now();
  const size_t count =
      std::min(size() - first, kStretchPerThread * static_cast<size_t>(num_threads_));
  stretch_.clear();  // the previous stretch goes before the next is read
  stretch_.resize(count);
  first_ = first;
  const auto read = [&](int64_t begin, int64_t end, int) {
    for (int64_t i = begin; i < end; ++i) {
      const size_t k = first + static_cast<size_t>(i);
      lidar::LidarSweep& sweep = stretch_[static_cast<size_t>(i)];
      const size_t index = k * static_cast<size_t>(stride_);
      sweep = dataset_.LoadSweep(index);
      if (selected_[k] || taken_[k]) continue;
      try {
        selected_[k] = estimation::SelectForBatch(sweep, pairing_);
      } catch (const Error& e) {
        throw Error(dataset_.SweepPath(index) + ": " + e.what());
      }
    }
  };
  try {
    ParallelFor(0, static_cast<int64_t>(count), num_threads_, read);
  } catch (...) {
    stretch_.clear();  // no half-read stretch is served later
    throw;
  }
  seconds_reading_ +=
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (progress_) progress_(static_cast<double>(first + count) / static_cast<double>(size()));
}

estimation::SelectedSweep KeyframeSweepReader::TakeSelected(size_t k) {
  if (k >= size() || !selected_[k]) {
    throw Error("KeyframeSweepReader: keyframe sweep " + std::to_string(k) +
                (k < size() && taken_[k] ? " was already taken" : " was never read"));
  }
  estimation::SelectedSweep out = std::move(*selected_[k]);
  selected_[k].reset();
  taken_[k] = true;
  return out;
}

}  // namespace internal
}  // namespace pipeline
}  // namespace autocal
