#pragma once

// The storage hand-off of point group factors, private to the library: a group of a few
// thousand points is a megabyte, which the allocator may hand back to the system when freed,
// so that its next use pays a page fault per 4 kB. The sliding window therefore takes a
// dropped group's storage back and edits it in place, or, emptied, fills it for another group.

#include <memory>
#include <utility>
#include <vector>

#include "autocal/factors/point_to_sweep_plane_group_factor.h"

namespace autocal {
namespace factors {

// A group's points' terms and their planes' sides, in the group's storage.
struct ReleasedPointGroup {
  std::vector<PointToSweepPlaneFactor::Terms> points;
  std::vector<PointToSweepPlaneFactor::Side> plane_sides;
};

class PointGroupStorage {
 public:
  // Consumes a factor no longer needed and returns its points' terms and plane sides in their
  // storage. Empty for a null factor.
  static ReleasedPointGroup Release(std::unique_ptr<PointToSweepPlaneGroupFactor> factor) {
    if (factor == nullptr) return {};
    return {std::move(factor->points_), std::move(factor->plane_sides_)};
  }
};

inline ReleasedPointGroup ReleasePoints(std::unique_ptr<PointToSweepPlaneGroupFactor> factor) {
  return PointGroupStorage::Release(std::move(factor));
}

}  // namespace factors
}  // namespace autocal
