#pragma once

// Collects decoded points into a lidar::PointCloud, applying the non-finite policy of
// PointCloudReadOptions and refusing values the cloud cannot store (an intensity beyond
// the float range would silently become infinite). Shared by the PLY and PCD readers.
// Private to src/io.

#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>

#include "autocal/lidar/point_cloud.h"
#include "io/scalar_type.h"
#include "io/text_format.h"

namespace autocal {
namespace io {
namespace internal {

// Per-point values in the order the builder expects them.
enum PointValue { kX = 0, kY, kZ, kIntensity, kTime, kNumPointValues };

// A file's per-point time (`t` or `time`) and its unit, which follows its type: a floating
// point property is seconds (Velodyne, autocal's own sweeps), an integer one nanoseconds
// (Ouster's and Livox's uint32 offsets), as the bag importer reads them (docs/import.md).
enum class PointTime { kNone, kSeconds, kNanoseconds };

inline PointTime PointTimeOf(bool found, ScalarType type) {
  if (!found) return PointTime::kNone;
  return IsIntegerType(type) ? PointTime::kNanoseconds : PointTime::kSeconds;
}

class PointCloudBuilder {
 public:
  enum class AddResult { kAdded, kDropped, kNonFinite, kOutOfRange };

  // `capacity` >= 0 is the number of points the file declares; the readers check it
  // against the file size before, so the allocation is bounded by the input.
  PointCloudBuilder(int64_t capacity, bool has_intensity, PointTime time, bool drop_non_finite)
      : has_intensity_(has_intensity),
        has_time_(time != PointTime::kNone),
        time_unit_s_(time == PointTime::kNanoseconds ? 1e-9 : 1.0),
        drop_non_finite_(drop_non_finite) {
    cloud_.points.resize(3, capacity);
    if (has_intensity_) cloud_.intensity.resize(capacity);
    if (has_time_) cloud_.time_s.resize(capacity);
  }

  // On kNonFinite / kOutOfRange, *bad_value is the index (PointValue) of the first
  // non-finite value / of the intensity beyond the float range or the time beyond
  // lidar::kMaxPointTimeS (x, y and z are stored as doubles, so every finite value fits). An
  // out-of-range value is an error even when non-finite points are dropped: the file holds a
  // number, not a "no return". values[kTime] is in the file's unit.
  AddResult Add(const double (&values)[kNumPointValues], int* bad_value) {
    for (int i = 0; i < kNumPointValues; ++i) {
      if ((i == kIntensity && !has_intensity_) || (i == kTime && !has_time_)) continue;
      if (!std::isfinite(values[i])) {
        *bad_value = i;
        return drop_non_finite_ ? AddResult::kDropped : AddResult::kNonFinite;
      }
    }
    if (has_intensity_ && std::abs(values[kIntensity]) > std::numeric_limits<float>::max()) {
      *bad_value = kIntensity;
      return AddResult::kOutOfRange;
    }
    const double time_s = time_unit_s_ * values[kTime];
    if (has_time_ && std::abs(time_s) > lidar::kMaxPointTimeS) {
      *bad_value = kTime;
      return AddResult::kOutOfRange;
    }
    cloud_.points.col(size_) << values[kX], values[kY], values[kZ];
    if (has_intensity_) cloud_.intensity[size_] = static_cast<float>(values[kIntensity]);
    if (has_time_) cloud_.time_s[size_] = time_s;
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
  double time_unit_s_;  // seconds per unit of the file's time
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

// Why Add returned kOutOfRange; `value` is the offending number, in the file's unit.
inline std::string OutOfRangeMessage(const char* noun, int64_t index, int bad_value, double value,
                                     PointTime time) {
  const std::string head =
      std::string(noun) + " " + std::to_string(index) + " has " + PointValueName(bad_value) + " ";
  if (bad_value != kTime) {
    return head + FormatDouble(value) +
           ", outside the range of a float (expected |value| <= 3.40282e+38)";
  }
  return head + FormatDouble(value) +
         (time == PointTime::kNanoseconds ? " (an integer property: nanoseconds)"
                                          : " (a floating point property: seconds)") +
         ", not a time within one sweep (expected |t| <= " + FormatDouble(lidar::kMaxPointTimeS) +
         " s after the sweep's stamp)";
}

// The error for a point Add refused, or nothing when it was added or dropped.
template <typename FailFunction>
void FailOnRefusedPoint(PointCloudBuilder::AddResult result, const char* noun, int64_t index,
                        int bad_value, const double (&values)[kNumPointValues], PointTime time,
                        FailFunction fail) {
  if (result == PointCloudBuilder::AddResult::kNonFinite) {
    fail(NonFiniteMessage(noun, index, bad_value));
  }
  if (result == PointCloudBuilder::AddResult::kOutOfRange) {
    fail(OutOfRangeMessage(noun, index, bad_value, values[bad_value], time));
  }
}

}  // namespace internal
}  // namespace io
}  // namespace autocal
