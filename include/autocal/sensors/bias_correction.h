#pragma once

// Preintegrated IMU deltas and their first-order correction for a change of the biases
// (docs/factors.md, Eq. F6-F7), written once for the preintegration's Predict, the IMU factor
// (analytic and autodiff) and the factors that attach through either:
//   dR(b) = dR Exp(d_R_d_bg (b_g - b_g_lin))
//   dv(b) = dv + d_v_d_bg (b_g - b_g_lin) + d_v_d_ba (b_a - b_a_lin)
//   dp(b) = dp + d_p_d_bg (b_g - b_g_lin) + d_p_d_ba (b_a - b_a_lin)
// The rotation Jacobian is on the right (body-frame) error of dR.

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "autocal/geometry/so3.h"

namespace autocal {
namespace sensors {

struct LinearizedDeltas {
  Eigen::Quaterniond delta_q = Eigen::Quaterniond::Identity();
  Eigen::Vector3d delta_v = Eigen::Vector3d::Zero();
  Eigen::Vector3d delta_p = Eigen::Vector3d::Zero();
  Eigen::Matrix3d d_R_d_bg = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d d_v_d_bg = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d d_v_d_ba = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d d_p_d_bg = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d d_p_d_ba = Eigen::Matrix3d::Zero();
  // The biases the deltas were integrated with.
  Eigen::Vector3d b_g_lin = Eigen::Vector3d::Zero();
  Eigen::Vector3d b_a_lin = Eigen::Vector3d::Zero();

  // The deltas at biases (b_g, b_a), for double and ceres::Jet. dp may be null when the
  // position is not wanted; phi_bg, when given, receives the rotation vector
  // d_R_d_bg (b_g - b_g_lin) of the correction (analytic Jacobians need it).
  template <typename T>
  void Corrected(const geometry::Vector3<T>& b_g, const geometry::Vector3<T>& b_a,
                 Eigen::Quaternion<T>* dq, geometry::Vector3<T>* dv, geometry::Vector3<T>* dp,
                 geometry::Vector3<T>* phi_bg = nullptr) const {
    const geometry::Vector3<T> dbg = b_g - b_g_lin.cast<T>();
    const geometry::Vector3<T> dba = b_a - b_a_lin.cast<T>();
    const geometry::Vector3<T> phi = d_R_d_bg.cast<T>() * dbg;
    *dq = delta_q.cast<T>() * geometry::Exp(phi);
    *dv = delta_v.cast<T>() + d_v_d_bg.cast<T>() * dbg + d_v_d_ba.cast<T>() * dba;
    if (dp != nullptr)
      *dp = delta_p.cast<T>() + d_p_d_bg.cast<T>() * dbg + d_p_d_ba.cast<T>() * dba;
    if (phi_bg != nullptr) *phi_bg = phi;
  }
};

}  // namespace sensors
}  // namespace autocal
