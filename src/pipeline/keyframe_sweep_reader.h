#pragma once

// The offline pipeline's keyframe sweeps (every sweep_stride-th sweep of the log) as a
// lidar::SweepSource for the initializer (docs/calibration.md, "Speed"). They are read in
// stretches on several threads; the first time a sweep is read it is also reduced to the
// points the batch solve uses (estimation::SelectForBatch). Only the current stretch is held
// whole, so a log's memory is that of its reduced sweeps, under a quarter of their size.

#include <cstddef>
#include <functional>
#include <optional>
#include <vector>

#include "autocal/estimation/lidar_inertial_batch.h"
#include "autocal/estimation/pairing_options.h"
#include "autocal/io/dataset.h"
#include "autocal/lidar/sweep_source.h"

namespace autocal {
namespace pipeline {
namespace internal {

class KeyframeSweepReader final : public lidar::SweepSource {
 public:
  // `progress`, when given, is called with the fraction of the sweeps read so far. The
  // dataset must outlive the reader.
  KeyframeSweepReader(const io::Dataset& dataset, int stride,
                      const estimation::PairingOptions& pairing, int num_threads,
                      std::function<void(double)> progress = {});

  size_t size() const override { return selected_.size(); }
  const lidar::LidarSweep& Sweep(size_t k) override;

  // Keyframe sweep k reduced for the batch, moved out (each is taken once). Throws
  // autocal::Error when sweep k was never read or is taken twice.
  estimation::SelectedSweep TakeSelected(size_t k);
  // Wall time spent reading and reducing sweeps.
  double seconds_reading() const { return seconds_reading_; }

 private:
  void ReadStretch(size_t first);

  const io::Dataset& dataset_;
  int stride_;
  estimation::PairingOptions pairing_;
  int num_threads_;
  std::function<void(double)> progress_;
  size_t first_ = 0;  // keyframe index of stretch_[0]
  std::vector<lidar::LidarSweep> stretch_;
  std::vector<std::optional<estimation::SelectedSweep>> selected_;
  std::vector<bool> taken_;
  double seconds_reading_ = 0.0;
};

}  // namespace internal
}  // namespace pipeline
}  // namespace autocal
