#pragma once

// A point cloud: points as a 3xN matrix (metres, in the frame the owner names), with
// optional per-point intensity and time. The lidar module's operations (transform,
// voxel grid, neighbour search, normals) work on this type.

#include <cstdint>
#include <string>

#include <Eigen/Core>

namespace autocal {
namespace lidar {

struct PointCloud {
  Eigen::Matrix3Xd points;
  // Empty, or one value per point.
  Eigen::VectorXf intensity;
  // Empty, or one value per point: seconds relative to the sweep stamp.
  Eigen::VectorXd time_s;

  int64_t size() const { return points.cols(); }
  bool empty() const { return points.cols() == 0; }
  bool has_intensity() const { return intensity.size() == points.cols() && !empty(); }
  bool has_time() const { return time_s.size() == points.cols() && !empty(); }
};

// One LiDAR sweep: the sweep's reference stamp (LiDAR clock) and its points in frame L.
struct LidarSweep {
  int64_t t_ns = 0;
  PointCloud cloud;
};

}  // namespace lidar
}  // namespace autocal
