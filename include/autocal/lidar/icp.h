#pragma once

// Iterative closest point (docs/lidar.md §4). Results are named by frame: T_target_source
// maps source points into the target frame, p_target = T_target_source * p_source.
//
// Pose updates and the covariance live in the tangent space of a LEFT perturbation in the
// target frame: T = Exp(delta) * T_hat with delta = [rho; phi] (geometry::ExpSE3 order,
// translation first), so IcpResult::covariance is Cov(delta) in m^2, m rad and rad^2.

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "autocal/factors/robust_loss.h"
#include "autocal/geometry/se3.h"
#include "autocal/lidar/kd_tree.h"
#include "autocal/lidar/normals.h"

namespace autocal {
namespace lidar {

using Matrix6d = Eigen::Matrix<double, 6, 6>;

// kGeneralized: Generalized-ICP (Segal, Haehnel, Thrun 2009) with plane-regularized point
// covariances (docs/lidar.md §4.7).
enum class IcpMethod { kPointToPoint, kPointToPlane, kGeneralized };

// "point_to_point" | "point_to_plane" | "gicp"; throws autocal::Error otherwise.
IcpMethod ParseIcpMethod(const std::string& name);
const char* IcpMethodName(IcpMethod method);

// Closed-form rigid alignment of known correspondences (course §7.2 steps 1-4, eqs.
// 4.1-4.4): the T_target_source minimizing sum_i w_i |target_i - T source_i|^2.
// `weights` is empty (all 1) or one non-negative weight per pair. Throws autocal::Error
// with fewer than 3 pairs (of positive weight), mismatched sizes, non-finite input, or
// collinear/coincident source points (the rotation about their line is undetermined).
geometry::Pose3d AlignCorrespondences(const Eigen::Matrix3Xd& source,
                                      const Eigen::Matrix3Xd& target,
                                      const Eigen::VectorXd& weights = Eigen::VectorXd());

struct IcpConvergenceOptions {
  // Upper bound on iterations (correspondence search + solve).
  int max_iterations = 30;
  // Converged when one iteration moves the estimate by less than both of these. 1e-4 m and
  // 1e-5 rad are far below LiDAR noise yet reached in a few Gauss-Newton steps.
  double translation_m = 1e-4;
  double rotation_rad = 1e-5;
};

// What point-to-plane and GICP alignment do with a direction of motion the correspondences do
// not constrain (docs/lidar.md, "Degeneracy": too few normals within 60 degrees of it, as a
// corridor's or tunnel's axis has): refuse the alignment, keep the guess's motion along it, or
// solve as if it were constrained and report it (IcpResult::weak_translations).
enum class IcpDegenerate { kRefuse, kHoldGuess, kReport };

struct IcpOptions {
  IcpMethod method = IcpMethod::kPointToPlane;
  IcpDegenerate degenerate = IcpDegenerate::kRefuse;
  // Pairs farther apart than this are not correspondences. About 4 voxels: wide enough to
  // pull in a start that is off by tens of centimetres, tight enough to ignore other
  // surfaces.
  double max_correspondence_m = 1.0;
  // Robust loss on the residual (point-to-plane distance, or point-to-point distance).
  factors::RobustKernel robust;
  IcpConvergenceOptions convergence;
  // Target points whose neighbourhood planarity is below this carry no plane
  // (point-to-plane only); 0 keeps every point with a defined normal.
  double min_target_planarity = 0.0;
  // Residual standard deviation (m) for the covariance; 0 estimates it from the final
  // weighted residuals (eq. 4.15).
  double residual_sigma_m = 0.0;
  // Point-to-plane only: when > 0, the source points' range noise (1-sigma, along the
  // beam from the source origin) is propagated per point instead, Censi's sandwich form
  // Cov = H^-1 (sum w^2 var_i J J^T) H^-1 with var_i = sigma_r^2 (n . R u_i)^2 (eq. 4.16).
  // Grazing ground returns then count with their small along-normal noise. Point-to-point
  // and GICP ignore it: their covariance is sigma^2 H^-1 (eq. 4.14).
  double source_range_sigma_m = 0.0;
  // Generalized-ICP: each point's covariance is its neighbourhood's plane, eigenvalues
  // (epsilon, 1, 1) along (normal, tangents); source normals from these neighbourhoods.
  double gicp_epsilon = 1e-3;
  NormalEstimationOptions source_normals;
  // Threads for the correspondence search and the normal equations of point-to-plane and
  // GICP alignment (common/parallel_for.h; point-to-point runs on one thread). The sums are
  // taken over fixed blocks of points added in order, so the result is the same bit for bit
  // on any number of threads.
  int num_threads = 1;
};

// How an IcpTarget provides normals for point-to-plane alignment.
enum class TargetNormals {
  kNone,      // point-to-point only
  kAll,       // every point's normal, computed when the target is built
  kOnDemand,  // a point's normal computed when an alignment first pairs a point with it:
              // a map registered against once computes a fraction of its normals
};

// A target cloud prepared once for many alignments: its k-d tree and, for point-to-plane,
// its normals.
class IcpTarget {
 public:
  // Throws autocal::Error on non-finite points. num_threads builds the tree and, for kAll,
  // estimates the normals.
  IcpTarget(Eigen::Matrix3Xd points, TargetNormals normals,
            const NormalEstimationOptions& normal_setting = {}, int num_threads = 1);
  IcpTarget(Eigen::Matrix3Xd points, bool with_normals,
            const NormalEstimationOptions& normal_setting = {})
      : IcpTarget(std::move(points), with_normals ? TargetNormals::kAll : TargetNormals::kNone,
                  normal_setting) {}

  const KdTree& tree() const { return tree_; }
  const Eigen::Matrix3Xd& points() const { return tree_.points(); }
  bool has_normals() const { return mode_ != TargetNormals::kNone; }
  // Every normal for kAll; for kOnDemand only those of points prepared so far (the others
  // are zero with planarity 0). For kOnDemand, read it only while no alignment runs
  // against this target: an alignment may be filling in columns.
  const SurfaceNormals& normals() const { return normals_; }

  // Makes sure the normals of the points with these indices exist (kOnDemand computes the
  // missing ones on num_threads threads; negative indices are skipped). Throws
  // autocal::Error, preparing nothing, when an index is not below the number of points. Safe
  // to call from concurrent alignments against the same target.
  void PrepareNormals(const std::vector<int>& indices, int num_threads) const;

 private:
  KdTree tree_;
  TargetNormals mode_;
  NormalEstimationOptions normal_setting_;
  // The on-demand cache: normals_ columns are written once, under mutex_, for the points
  // whose `prepared_` flag is still 0.
  mutable SurfaceNormals normals_;
  mutable std::vector<uint8_t> prepared_;
  mutable std::unique_ptr<std::mutex> mutex_ = std::make_unique<std::mutex>();
};

struct IcpResult {
  geometry::Pose3d T_target_source;
  // Cov of the left perturbation [rho; phi] (eq. 4.14), see the file comment.
  Matrix6d covariance = Matrix6d::Zero();
  int iterations = 0;
  bool converged = false;
  // Source points with a correspondence at the final estimate, and their fraction.
  int num_correspondences = 0;
  double fitness = 0.0;
  // RMS of the residuals of those correspondences (point-to-plane distance for
  // point-to-plane, point distance for point-to-point), unweighted.
  double inlier_rmse_m = 0.0;
  // The residual sigma, given (IcpOptions::residual_sigma_m) or estimated (eq. 4.15). The
  // covariance is sigma^2 H^-1 with it (eq. 4.14), except for point-to-plane with
  // source_range_sigma_m > 0, whose covariance (eq. 4.16) does not use it.
  double residual_sigma_m = 0.0;
  // IcpDegenerate::kHoldGuess and kReport: the directions the correspondences left
  // unconstrained, unit vectors in the target frame, each signed with its largest component
  // positive. Under kHoldGuess the motion along them is the guess's, taken at the guessed
  // place of the source points' centroid (translations of that point, rotations about axes
  // through it), and the covariance holds the other directions only: taken at that point it is
  // zero along these, where the clouds say nothing. Under kReport the solve and the covariance
  // are those of a constrained alignment: the motion along these rests on a few
  // correspondences, or on none.
  std::vector<Eigen::Vector3d> weak_translations;
  std::vector<Eigen::Vector3d> weak_rotation_axes;
};

// Aligns `source` to `target` starting from `T_target_source_guess` (e.g. from a motion
// model). Throws autocal::Error on non-finite input, when the target lacks normals for
// point-to-plane, when too few correspondences are found (fewer than 6), or when the
// geometry leaves a direction of motion unconstrained (unless IcpOptions::degenerate holds it).
IcpResult AlignIcp(const Eigen::Matrix3Xd& source, const IcpTarget& target,
                   const geometry::Pose3d& T_target_source_guess, const IcpOptions& setting);

}  // namespace lidar
}  // namespace autocal
