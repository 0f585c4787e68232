#pragma once

// Pairwise registration of two point clouds as one call (docs/lidar.md §4.6): voxel
// downsampling of both clouds, target k-d tree and normals, ICP. autocal_register is a thin
// command-line layer over this.

#include <string>

#include "autocal/geometry/se3.h"
#include "autocal/lidar/icp.h"
#include "autocal/lidar/normals.h"
#include "autocal/lidar/point_cloud.h"

namespace autocal {
namespace lidar {

struct RegistrationOptions {
  // Voxel edge for both clouds (0 = use every point). 0.25 m keeps the geometry of a street
  // scan while cutting 70k points to about 6k.
  double voxel_m = 0.25;
  // Neighbourhoods for the target normals (point-to-plane only): 10 neighbours, no
  // distance bound (on the real scan pair a 1 m bound leaves sparse far surfaces without
  // normals and costs accuracy, docs/lidar.md §4.6).
  NormalEstimationOptions target_normals;
  IcpOptions icp;
};

struct RegistrationResult {
  IcpResult icp;
  int64_t source_points = 0;  // after downsampling
  int64_t target_points = 0;
  // Wall time of downsampling, target preparation and alignment.
  double time_s = 0.0;
};

// Builds a setting from the command-line vocabulary of autocal_register, validating every
// value: method "point_to_point" | "point_to_plane" | "gicp", loss "none" | "huber" | "cauchy",
// positive loss scale and correspondence distance, voxel >= 0. Throws autocal::Error naming
// the offending option.
RegistrationOptions MakeRegistrationOptions(const std::string& method, const std::string& loss,
                                            double loss_scale_m, double voxel_m,
                                            double max_correspondence_m);

// The initial guess T_target_source of autocal_register --init, from either form:
//   "x,y,z,roll,pitch,yaw"  metres and degrees, R = Rz(yaw) Ry(pitch) Rx(roll);
//   a 4x4 homogeneous matrix as 16 numbers (row by row, separated by spaces, commas, brackets
//   or line breaks), whose rotation block is orthonormal to 1e-4 (six printed digits
//   suffice) and last row 0 0 0 1.
// `what` names the text's origin in errors (a file name, or "--init"). Throws autocal::Error
// saying which number (with its line and column) or which property is wrong.
geometry::Pose3d ParsePoseGuess(const std::string& text, const std::string& what);
// The matrix form's checks and conversion alone.
geometry::Pose3d PoseGuessFromMatrix(const Eigen::Matrix4d& m, const std::string& what);

// Throws autocal::Error on empty clouds, non-finite points or a failed alignment (see
// AlignIcp). Points with non-finite coordinates are rejected, not dropped: clean the
// clouds with RemoveNonFinite first if that is intended.
RegistrationResult RegisterPointClouds(const PointCloud& source, const PointCloud& target,
                                       const geometry::Pose3d& T_target_source_guess,
                                       const RegistrationOptions& setting);

// Human-readable report: T_target_source (4x4), inlier RMSE, iterations, time, 6x6
// covariance.
std::string FormatRegistrationReport(const RegistrationResult& result,
                                     const RegistrationOptions& setting);

// The same as YAML (keys: T_target_source, q_xyzw, p_m, covariance, inlier_rmse_m, ...).
std::string FormatRegistrationYaml(const RegistrationResult& result,
                                   const RegistrationOptions& setting);

}  // namespace lidar
}  // namespace autocal
