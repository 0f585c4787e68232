#pragma once

// Collects decoded points into a lidar::PointCloud, applying the non-finite policy of
// PointCloudReadOptions. Shared by the PLY and PCD readers. Private to src/io.

#include <cmath>
#include <cstdint>
#include <string>
#include <utility>

#include "autocal/lidar/point_cloud.h"

namespace autocal {
namespace io {
namespace internal {

// Per-point values in the order the builder expects them.
enum PointValue { kX = 0, kY, kZ, kIntensity, kTime, kNumPointValues };

class PointCloudBuilder {
 public:
  enum class AddResult { kAdded, kDropped, kNonFinite };

  PointCloudBuilder(int64_t capacity, bool has_intensity, bool has_time, bool drop_non_finite)
      : has_intensity_(has_intensity), has_time_(has_time), drop_non_finite_(drop_non_finite) {
    cloud_.points.resize(3, capacity);
    if (has_intensity_) cloud_.intensity.resize(capacity);
    if (has_time_) cloud_.time_s.resize(capacity);
  }

  // On kNonFinite, *bad_value is the index (PointValue) of the first non-finite value.
  AddResult Add(const double (&values)[kNumPointValues], int* bad_value) {
    for (int i = 0; i < kNumPointValues; ++i) {
      if ((i == kIntensity && !has_intensity_) || (i == kTime && !has_time_)) continue;
      if (!std::isfinite(values[i])) {
        *bad_value = i;
        return drop_non_finite_ ? AddResult::kDropped : AddResult::kNonFinite;
      }
    }
    cloud_.points.col(size_) << values[kX], values[kY], values[kZ];
    if (has_intensity_) cloud_.intensity[size_] = static_cast<float>(values[kIntensity]);
    if (has_time_) cloud_.time_s[size_] = values[kTime];
    ++size_;
    return AddResult::kAdded;
  }

  lidar::PointCloud Finish() {
    cloud_.points.conservativeResize(3, size_);
    if (has_intensity_) cloud_.intensity.conservativeResize(size_);
    if (has_time_) cloud_.time_s.conservativeResize(size_);
    return std::move(cloud_);
  }

 private:
  lidar::PointCloud cloud_;
  int64_t size_ = 0;
  bool has_intensity_;
  bool has_time_;
  bool drop_non_finite_;
};

inline const char* PointValueName(int value) {
  static const char* const kNames[kNumPointValues] = {"x", "y", "z", "intensity", "time"};
  return kNames[value];
}

// Why a point cannot be added: `noun` names it in the file's own terms ("point",
// "vertex"), `bad_value` is the PointValue that is not finite.
inline std::string NonFiniteMessage(const char* noun, int64_t index, int bad_value) {
  return std::string(noun) + " " + std::to_string(index) + " has a non-finite " +
         PointValueName(bad_value) +
         " (set PointCloudReadOptions::drop_non_finite_points to drop such points)";
}

}  // namespace internal
}  // namespace io
}  // namespace autocal
