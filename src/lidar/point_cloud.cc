#include "autocal/lidar/point_cloud.h"

#include <cmath>
#include <sstream>

#include "autocal/common/error.h"

namespace autocal {
namespace lidar {
namespace {

// The index of the first column of `values` with a non-finite entry; -1 when all are finite.
// One vectorized pass first: the loop runs only on bad input.
template <typename Values>
int64_t FirstNonFinite(const Values& values) {
  if (values.allFinite()) return -1;
  int64_t i = 0;
  while (values.col(i).allFinite()) ++i;
  return i;
}

PointCloud WithPoints(const PointCloud& cloud, Eigen::Matrix3Xd points) {
  PointCloud out;
  out.points = std::move(points);
  out.intensity = cloud.intensity;
  out.time_s = cloud.time_s;
  return out;
}

}  // namespace

PointCloud Translate(const PointCloud& cloud, const Eigen::Vector3d& t) {
  return WithPoints(cloud, cloud.points.colwise() + t);
}

PointCloud Rotate(const PointCloud& cloud, const Eigen::Matrix3d& R) {
  constexpr double kTolerance = 1e-6;
  if (!(R.transpose() * R).isIdentity(kTolerance) || std::abs(R.determinant() - 1.0) > kTolerance) {
    std::ostringstream message;
    message << "Rotate: the matrix is not a rotation (R^T R != I or det != 1):\n" << R;
    throw Error(message.str());
  }
  return WithPoints(cloud, R * cloud.points);
}

PointCloud Scale(const PointCloud& cloud, const Eigen::Vector3d& s) {
  return WithPoints(cloud, s.asDiagonal() * cloud.points);
}

PointCloud Scale(const PointCloud& cloud, double k) { return WithPoints(cloud, k * cloud.points); }

PointCloud Transform(const PointCloud& cloud_b, const geometry::Pose3d& T_a_b) {
  return WithPoints(cloud_b, (T_a_b.R() * cloud_b.points).colwise() + T_a_b.p);
}

void TransformInPlace(const geometry::Pose3d& T_a_b, PointCloud* cloud) {
  const Eigen::Matrix3d R = T_a_b.R();
  cloud->points = (R * cloud->points).colwise() + T_a_b.p;
}

void CheckPointCloud(const PointCloud& cloud, const std::string& what) {
  const int64_t n = cloud.size();
  if (cloud.intensity.size() != 0 && cloud.intensity.size() != n) {
    throw Error(what + ": " + std::to_string(cloud.intensity.size()) + " intensity values for " +
                std::to_string(n) + " points");
  }
  if (cloud.time_s.size() != 0 && cloud.time_s.size() != n) {
    throw Error(what + ": " + std::to_string(cloud.time_s.size()) + " time values for " +
                std::to_string(n) + " points");
  }
  const int64_t bad_point = FirstNonFinite(cloud.points);
  if (bad_point >= 0) {
    throw Error(what + ": point " + std::to_string(bad_point) + " has a non-finite coordinate");
  }
  const int64_t bad_intensity = FirstNonFinite(cloud.intensity.transpose());
  if (bad_intensity >= 0) {
    throw Error(what + ": point " + std::to_string(bad_intensity) +
                " has a non-finite intensity (" + std::to_string(cloud.intensity(bad_intensity)) +
                ")");
  }
  const int64_t bad_time = FirstNonFinite(cloud.time_s.transpose());
  if (bad_time >= 0) {
    throw Error(what + ": point " + std::to_string(bad_time) + " has a non-finite time (" +
                std::to_string(cloud.time_s(bad_time)) + " s)");
  }
}

PointCloud RemoveNonFinite(const PointCloud& cloud) {
  const int64_t n = cloud.size();
  PointCloud out;
  out.points.resize(3, n);
  if (cloud.has_intensity()) out.intensity.resize(n);
  if (cloud.has_time()) out.time_s.resize(n);
  int64_t kept = 0;
  for (int64_t i = 0; i < n; ++i) {
    if (!cloud.points.col(i).allFinite()) continue;
    if (cloud.has_intensity() && !std::isfinite(cloud.intensity(i))) continue;
    if (cloud.has_time() && !std::isfinite(cloud.time_s(i))) continue;
    out.points.col(kept) = cloud.points.col(i);
    if (cloud.has_intensity()) out.intensity(kept) = cloud.intensity(i);
    if (cloud.has_time()) out.time_s(kept) = cloud.time_s(i);
    ++kept;
  }
  out.points.conservativeResize(3, kept);
  if (cloud.has_intensity()) out.intensity.conservativeResize(kept);
  if (cloud.has_time()) out.time_s.conservativeResize(kept);
  return out;
}

}  // namespace lidar
}  // namespace autocal
