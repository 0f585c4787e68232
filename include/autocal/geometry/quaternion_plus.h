#pragma once

// The right update of an orientation by a rotation vector in its body frame,
// q [+] phi = q * Exp(phi), renormalized (docs/design.md, "Perturbations"): the one lift of a
// tangent step onto a unit quaternion, used by RightQuaternionManifold::Plus, by the steps of
// the calibration blocks and by attitude integration alike.

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "autocal/geometry/so3.h"

namespace autocal {
namespace geometry {

template <typename QuaternionDerived, typename VectorDerived>
Eigen::Quaternion<typename QuaternionDerived::Scalar> QuaternionPlus(
    const Eigen::QuaternionBase<QuaternionDerived>& q,
    const Eigen::MatrixBase<VectorDerived>& phi) {
  return (q * Exp(phi)).normalized();
}

}  // namespace geometry
}  // namespace autocal
