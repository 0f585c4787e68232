#pragma once

// The IMU pose of a keyframe propagated to its sweep's points (Eq. P1-P3 at delta = 0), shared
// by the points of one LiDAR firing: they carry one time, so consecutive points with equal
// times take the same motion and pose, formed once (docs/sliding_window.md, "Shared firing
// poses"). Used by the sliding window and the batch solver alike.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <limits>

#include "autocal/factors/point_to_plane_factor.h"

namespace autocal {
namespace estimation {
namespace internal {

class FiringPoses {
 public:
  // The keyframe's state; the references must outlive this object.
  FiringPoses(const Eigen::Quaterniond& q_W_I, const Eigen::Vector3d& p_W_I,
              const Eigen::Vector3d& v_W_I, const Eigen::Vector3d& g_W)
      : q_W_I_(q_W_I), p_W_I_(p_W_I), v_W_I_(v_W_I), g_W_(g_W) {}

  // The pose at a point's time (seconds after the sweep's stamp). When the time differs from
  // the last call's, the motion is asked of motion_at() (returning a factors::PointMotion) and
  // the pose propagated anew; otherwise both are the last call's.
  template <typename MotionAt>
  const factors::PropagatedPose<double>& At(double point_time_s, const MotionAt& motion_at) {
    if (!(point_time_s == time_s_)) {
      motion_ = motion_at();
      pose_ = factors::PropagateKeyframe(q_W_I_, p_W_I_, v_W_I_, 0.0, motion_, g_W_);
      time_s_ = point_time_s;
    }
    return pose_;
  }
  // The motion of the last call's time.
  const factors::PointMotion& motion() const { return motion_; }

 private:
  const Eigen::Quaterniond& q_W_I_;
  const Eigen::Vector3d& p_W_I_;
  const Eigen::Vector3d& v_W_I_;
  const Eigen::Vector3d& g_W_;
  double time_s_ = std::numeric_limits<double>::quiet_NaN();
  factors::PointMotion motion_;
  factors::PropagatedPose<double> pose_;
};

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
