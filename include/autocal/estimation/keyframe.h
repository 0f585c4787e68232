#pragma once

// The state of one keyframe as the estimators hold it: its pose, velocity and IMU biases at
// one IMU-clock stamp, each member a Ceres parameter block (DESIGN.md "State").

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>

namespace autocal {
namespace estimation {

struct Keyframe {
  int64_t t_ns = 0;  // IMU clock
  Eigen::Quaterniond q_W_I = Eigen::Quaterniond::Identity();
  Eigen::Vector3d p_W_I = Eigen::Vector3d::Zero();
  Eigen::Vector3d v_W_I = Eigen::Vector3d::Zero();
  Eigen::Vector3d b_g = Eigen::Vector3d::Zero();
  Eigen::Vector3d b_a = Eigen::Vector3d::Zero();
};

}  // namespace estimation
}  // namespace autocal
