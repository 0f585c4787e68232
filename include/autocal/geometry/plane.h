#pragma once

// A plane in normal form: the type the plane fits of lidar/ produce and the point-to-plane
// factors of factors/ consume, so it sits below both.

#include <Eigen/Core>

namespace autocal {
namespace geometry {

// The plane {p : normal . p + d = 0} with a unit normal; SignedDistance is positive on the
// side the normal points to.
struct Plane {
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  double d = 0.0;

  double SignedDistance(const Eigen::Vector3d& p) const { return normal.dot(p) + d; }
};

}  // namespace geometry
}  // namespace autocal
