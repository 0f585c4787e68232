#pragma once

// The state of one keyframe as the estimators hold it: its pose, velocity and IMU biases at
// one IMU-clock stamp, each member a Ceres parameter block (DESIGN.md "State").

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <functional>
#include <vector>

#include "autocal/sensors/calibration.h"

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

// Sets keyframes and a calibration in place: to the truth of a simulated log
// (evaluation::TruthSetter) for pipeline::OfflineCalibrationOptions::set_to_truth.
using StateSetter = std::function<void(std::vector<Keyframe>*, sensors::Calibration*)>;

}  // namespace estimation
}  // namespace autocal
