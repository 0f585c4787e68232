#pragma once

// A smooth analytic IMU trajectory with exact velocity and body rate, and the point motion
// (docs/estimation.md, Eq. P1-P3) that IMU propagation yields on it: the ground truth of the
// LiDAR factor tests.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>

#include "autocal/factors/point_to_plane_factor.h"
#include "autocal/geometry/so3.h"

namespace autocal {
namespace test {

inline const Eigen::Vector3d kGravity(0.0, 0.0, -9.80665);

// A smooth analytic IMU trajectory with exact velocity and body rate:
// R(t) = Exp(phi(t)), so R'(t) = R(t) Hat(Jr(phi) phi'(t)).
struct AnalyticTrajectory {
  Eigen::Vector3d Position(double t) const {
    return {3.0 * t + 0.5 * std::sin(t), 2.0 * std::cos(0.7 * t), 0.1 * t * t};
  }
  Eigen::Vector3d Velocity(double t) const {
    return {3.0 + 0.5 * std::cos(t), -1.4 * std::sin(0.7 * t), 0.2 * t};
  }
  Eigen::Vector3d Phi(double t) const {
    return {0.1 * std::sin(t), 0.2 * std::cos(0.5 * t), 0.8 * t - 1.0};
  }
  Eigen::Vector3d PhiDot(double t) const {
    return {0.1 * std::cos(t), -0.1 * std::sin(0.5 * t), 0.8};
  }
  Eigen::Quaterniond Rotation(double t) const { return geometry::Exp(Phi(t)); }
  Eigen::Vector3d BodyRate(double t) const { return geometry::RightJacobian(Phi(t)) * PhiDot(t); }
};

// What IMU propagation from keyframe time t_k to t_k + dt yields on this trajectory.
inline factors::PointMotion TrueMotion(const AnalyticTrajectory& traj, double t_k, double dt) {
  const Eigen::Quaterniond q_k = traj.Rotation(t_k);
  const double t = t_k + dt;
  factors::PointMotion motion;
  motion.dt_s = dt;
  motion.delta_q = q_k.conjugate() * traj.Rotation(t);
  motion.delta_v = q_k.conjugate() * (traj.Velocity(t) - traj.Velocity(t_k) - kGravity * dt);
  motion.delta_p = q_k.conjugate() * (traj.Position(t) - traj.Position(t_k) -
                                      traj.Velocity(t_k) * dt - 0.5 * kGravity * dt * dt);
  motion.omega_rad_s = traj.BodyRate(t);
  return motion;
}

}  // namespace test
}  // namespace autocal
