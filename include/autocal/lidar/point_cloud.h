#pragma once

// A point cloud: points as a 3xN matrix (metres, in the frame the owner names), with
// optional per-point intensity and time. The lidar module's operations (transform,
// voxel grid, neighbour search, normals) work on this type.

#include <Eigen/Core>
#include <cstdint>
#include <string>

#include "autocal/geometry/se3.h"

namespace autocal {
namespace lidar {

// A point's time further than this from its sweep's stamp is not a time within one sweep
// (a sweep lasts 0.05 to 0.2 s): the readers refuse it (a time in the wrong unit).
constexpr double kMaxPointTimeS = 1.0;

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

// Batch spatial operations (docs/lidar.md §2). Each returns a new cloud that keeps the
// intensity and time channels; points are columns, so every operation is one matrix
// expression over the 3xN block.

// p' = p + t for every point.
PointCloud Translate(const PointCloud& cloud, const Eigen::Vector3d& t);
// p' = R p. R must be a rotation (orthonormal, det +1); throws autocal::Error otherwise.
PointCloud Rotate(const PointCloud& cloud, const Eigen::Matrix3d& R);
// p' = diag(s) p (anisotropic scaling, eq. 2.1); Scale(cloud, k) is the isotropic case.
PointCloud Scale(const PointCloud& cloud, const Eigen::Vector3d& s);
PointCloud Scale(const PointCloud& cloud, double k);
// Points of frame b expressed in frame a: p_a = T_a_b * p_b.
PointCloud Transform(const PointCloud& cloud_b, const geometry::Pose3d& T_a_b);
void TransformInPlace(const geometry::Pose3d& T_a_b, PointCloud* cloud);

// Throws autocal::Error naming `what` when the optional channels do not match the number
// of points, or a coordinate, an intensity or a time is not finite (the message names the
// first such point by its index).
void CheckPointCloud(const PointCloud& cloud, const std::string& what);

// The cloud without points that have a non-finite coordinate, intensity or time (organized
// PCD files mark missing returns with NaN), so that it passes CheckPointCloud. Keeps the
// optional channels aligned.
PointCloud RemoveNonFinite(const PointCloud& cloud);

}  // namespace lidar
}  // namespace autocal
