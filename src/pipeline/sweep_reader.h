#pragma once

// The streamed sweeps of the online estimation, read from disk in stream order
// (docs/pipeline.md, "Online estimation").

#include <cstddef>
#include <future>
#include <system_error>

#include "autocal/io/dataset.h"
#include "autocal/lidar/point_cloud.h"

namespace autocal {
namespace pipeline {
namespace internal {

// Take(i) returns dataset.LoadSweep(i). With read-ahead, it then starts reading sweep i + 1 on
// another thread, which the window's processing of sweep i hides; a sweep that cannot be read
// throws its error from Take, as without the read-ahead. The dataset must outlive the reader.
class SweepReader {
 public:
  SweepReader(const io::Dataset& dataset, bool read_ahead)
      : dataset_(dataset), read_ahead_(read_ahead) {}
  SweepReader(const SweepReader&) = delete;  // a read under way refers to this reader
  SweepReader& operator=(const SweepReader&) = delete;

  lidar::LidarSweep Take(size_t index) {
    lidar::LidarSweep sweep =
        next_.valid() && next_index_ == index ? next_.get() : dataset_.LoadSweep(index);
    if (next_.valid()) next_.wait();  // a read-ahead of another sweep is not taken
    next_ = std::future<lidar::LidarSweep>();
    if (read_ahead_ && index + 1 < dataset_.lidar_sweeps.size()) {
      next_index_ = index + 1;
      try {
        next_ =
            std::async(std::launch::async, [this, index] { return dataset_.LoadSweep(index + 1); });
      } catch (const std::system_error&) {
        read_ahead_ = false;  // no thread to be had: read when due, as without read-ahead
      }
    }
    return sweep;
  }

 private:
  const io::Dataset& dataset_;
  bool read_ahead_;
  size_t next_index_ = 0;
  std::future<lidar::LidarSweep> next_;
};

}  // namespace internal
}  // namespace pipeline
}  // namespace autocal
