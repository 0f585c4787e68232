#include "autocal/lidar/icp.h"

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/parallel_for.h"

namespace autocal {
namespace lidar {
namespace {

using Vector6d = Eigen::Matrix<double, 6, 1>;

// A Gauss-Newton system needs 6 independent constraints; below this a solve is noise.
constexpr int kMinCorrespondences = 6;
// Source points summed together in a linearization's partial sums (SumOverMatchedPlanes).
constexpr int64_t kPointsPerPartialSum = 256;
// Relative size of the smallest eigenvalue of J^T W J below which a motion direction is
// treated as unconstrained.
constexpr double kDegenerateEigenRatio = 1e-10;
// A correspondence constrains a direction when its normal (its lever, for a rotation) lies
// within 60 degrees of it (docs/lidar.md, "Degeneracy").
constexpr double kAlignedCosine = 0.5;
// The share of the correspondences a direction needs aligned with it: at least 1 in 200.
constexpr int kAlignedShareDivisor = 200;
// Only a target neighbourhood this planar counts as looking along its normal: a line's (a
// beam's trace on a far wall) PCA normal is any direction across it. 0.3 is a patch about
// half as wide as it is long ((l1 - l0) / l2 of normals.h).
constexpr double kCountedPlanarity = 0.3;

struct WeightedPair {
  Eigen::Vector3d source;
  Eigen::Vector3d target;
  double weight;
};

void RequireFinite(const Eigen::Matrix3Xd& points, const char* what) {
  if (!points.allFinite()) {
    throw Error(std::string(what) + " contains a non-finite coordinate");
  }
}

// Eqs. (4.1)-(4.4): weighted centroids, cross-covariance W, SVD with the determinant
// correction, translation from the centroids.
geometry::Pose3d SolveRigid(const std::vector<WeightedPair>& pairs) {
  double weight_sum = 0.0;
  int positive = 0;
  Eigen::Vector3d mu_source = Eigen::Vector3d::Zero();
  Eigen::Vector3d mu_target = Eigen::Vector3d::Zero();
  for (const WeightedPair& pair : pairs) {
    weight_sum += pair.weight;
    positive += pair.weight > 0.0;
    mu_source += pair.weight * pair.source;
    mu_target += pair.weight * pair.target;
  }
  if (positive < 3 || !(weight_sum > 0.0)) {
    throw Error("rigid alignment needs at least 3 correspondences with positive weight, got " +
                std::to_string(positive));
  }
  mu_source /= weight_sum;  // eq. (4.1)
  mu_target /= weight_sum;
  Eigen::Matrix3d W = Eigen::Matrix3d::Zero();  // eq. (4.2), target x source
  Eigen::Matrix3d source_scatter = Eigen::Matrix3d::Zero();
  for (const WeightedPair& pair : pairs) {
    const Eigen::Vector3d ds = pair.source - mu_source;
    W.noalias() += pair.weight * (pair.target - mu_target) * ds.transpose();
    source_scatter.noalias() += pair.weight * ds * ds.transpose();
  }
  const Eigen::Vector3d spread =
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(source_scatter, Eigen::EigenvaluesOnly)
          .eigenvalues();  // ascending
  if (!(spread(1) > 1e-12 * spread(2))) {
    throw Error(
        "rigid alignment is undetermined: the source points are collinear or coincident, so "
        "the rotation about their line cannot be recovered");
  }
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(W, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Vector3d s = svd.singularValues();
  if (!(s(1) > 1e-12 * s(0))) {
    throw Error(
        "rigid alignment is undetermined: the matched target points are collinear or "
        "coincident");
  }
  const Eigen::Matrix3d& U = svd.matrixU();
  const Eigen::Matrix3d& V = svd.matrixV();
  // eq. (4.3): D flips the axis of the smallest singular value when U V^T is a reflection.
  const Eigen::Vector3d d(1.0, 1.0, U.determinant() * V.determinant());
  const Eigen::Matrix3d R = U * d.asDiagonal() * V.transpose();
  const Eigen::Vector3d t = mu_target - R * mu_source;  // eq. (4.4)
  return geometry::Pose3d(Eigen::Quaterniond(R).normalized(), t);
}

// Sums of one linearization: H = sum w J^T J, g = sum w J^T r (eqs. 4.8-4.10).
struct NormalEquations {
  Matrix6d H = Matrix6d::Zero();
  Vector6d g = Vector6d::Zero();
  // sum w^2 var_i J J^T of eq. (4.16), when the source range noise is given.
  Matrix6d propagated = Matrix6d::Zero();
  double weighted_squared_residuals = 0.0;
  double squared_residuals = 0.0;
  int count = 0;
  // Scalar residuals per correspondence: 1 for point-to-plane, 3 for point-to-point.
  int residual_dimension = 1;
};

// Point-to-plane linearization at T (eqs. 4.6-4.10): r = n . (T p - q) and, for the left
// perturbation about the centre c, dr/d[rho; phi] = [n; (T p - c) x n] (eq. 4.7c).
// Correspondences are searched first, then the target's normals for them are prepared, then
// the equations are summed in fixed blocks of points and combined in block order.
//
// `matches_io` holds each source point's match of the previous iteration (-1: none; empty on
// the first) and returns this one's. The nearest target point is no farther than the previous
// match, so the search starts with that distance as its bound, just above it so that the
// previous match itself still counts: the same match as with max_correspondence_m, found
// with less of the tree searched.
void MatchNearest(const Eigen::Matrix3Xd& source, const IcpTarget& target,
                  const geometry::Pose3d& T, const IcpOptions& setting,
                  std::vector<int>* matches_io) {
  const Eigen::Matrix3d R = T.R();
  const Eigen::Index n = source.cols();
  std::vector<int>& matches = *matches_io;
  if (matches.size() != static_cast<size_t>(n)) matches.assign(static_cast<size_t>(n), -1);
  const Eigen::Matrix3Xd& target_points = target.points();
  ParallelFor(0, n, setting.num_threads, [&](int64_t begin, int64_t end, int /*chunk*/) {
    Neighbor nearest;
    for (int64_t i = begin; i < end; ++i) {
      const Eigen::Vector3d p = R * source.col(i) + T.p;
      int& match = matches[static_cast<size_t>(i)];
      double bound_m = setting.max_correspondence_m;
      if (match >= 0) {
        const double previous_m = (p - target_points.col(match)).norm();
        bound_m = std::min(bound_m, previous_m * (1.0 + 1e-9) + 1e-12);
      }
      match = target.tree().Nearest(p, bound_m, &nearest) ? nearest.index : -1;
    }
  });
  target.PrepareNormals(matches, setting.num_threads);
}

// The per-block sums of a linearization, combined in block order.
NormalEquations Combined(const std::vector<NormalEquations>& partial, int residual_dimension) {
  NormalEquations eq = partial.front();
  for (size_t block = 1; block < partial.size(); ++block) {
    eq.H += partial[block].H;
    eq.propagated += partial[block].propagated;
    eq.g += partial[block].g;
    eq.weighted_squared_residuals += partial[block].weighted_squared_residuals;
    eq.squared_residuals += partial[block].squared_residuals;
    eq.count += partial[block].count;
  }
  eq.residual_dimension = residual_dimension;
  return eq;
}

// Whether a target point with this planarity carries a plane for point-to-plane and GICP:
// planarity 0 marks a point without a normal (EstimateNormals).
bool CarriesPlane(double planarity, const IcpOptions& setting) {
  return planarity > 0.0 && planarity >= setting.min_target_planarity;
}

// The sums of one linearization over the source points matched at T to a target point with a
// plane (planarity above 0 and min_target_planarity): `add(eq, i, match, p)` adds source point
// i, at p = T source_i, to its block's sums, or returns without adding to skip it. The points
// are summed in fixed blocks of kPointsPerPartialSum, whatever the thread count, and the
// blocks combined in order: the sums, and so the alignment, do not depend on the threads.
template <typename Add>
NormalEquations SumOverMatchedPlanes(const Eigen::Matrix3Xd& source, const IcpTarget& target,
                                     const geometry::Pose3d& T, const IcpOptions& setting,
                                     std::vector<int>* matches_io, Add add) {
  MatchNearest(source, target, T, setting, matches_io);
  const std::vector<int>& matches = *matches_io;
  const Eigen::Matrix3d R = T.R();
  const Eigen::Index n = source.cols();
  const Eigen::VectorXd& planarity = target.normals().planarity;
  const int64_t blocks =
      std::max<int64_t>(1, (n + kPointsPerPartialSum - 1) / kPointsPerPartialSum);
  std::vector<NormalEquations> partial(static_cast<size_t>(blocks));
  ParallelFor(0, blocks, setting.num_threads, [&](int64_t first_block, int64_t end_block, int) {
    for (int64_t block = first_block; block < end_block; ++block) {
      NormalEquations& eq = partial[static_cast<size_t>(block)];
      const int64_t end = std::min<int64_t>(n, (block + 1) * kPointsPerPartialSum);
      for (int64_t i = block * kPointsPerPartialSum; i < end; ++i) {
        const int match = matches[static_cast<size_t>(i)];
        if (match < 0) continue;
        if (!CarriesPlane(planarity(match), setting)) continue;
        add(eq, i, match, Eigen::Vector3d(R * source.col(i) + T.p));
      }
    }
  });
  return Combined(partial, 1);
}

NormalEquations LinearizePointToPlane(const Eigen::Matrix3Xd& source, const IcpTarget& target,
                                      const geometry::Pose3d& T, const Eigen::Vector3d& centre,
                                      const IcpOptions& setting, std::vector<int>* matches_io) {
  const Eigen::Matrix3d R = T.R();
  return SumOverMatchedPlanes(
      source, target, T, setting, matches_io,
      [&](NormalEquations& eq, int64_t i, int match, const Eigen::Vector3d& p) {
        const Eigen::Vector3d normal = target.normals().normals.col(match);
        const double r = normal.dot(p - target.points().col(match));
        Vector6d J;
        J.head<3>() = normal;
        J.tail<3>() = (p - centre).cross(normal);
        const double w = setting.robust.Weight(r);
        eq.H.noalias() += (w * J) * J.transpose();
        if (setting.source_range_sigma_m > 0.0) {
          const double along_normal = normal.dot(R * source.col(i).normalized());
          const double variance = std::pow(setting.source_range_sigma_m * along_normal, 2);
          eq.propagated.noalias() += (w * w * variance * J) * J.transpose();
        }
        eq.g.noalias() += (w * r) * J;
        eq.weighted_squared_residuals += w * r * r;
        eq.squared_residuals += r * r;
        ++eq.count;
      });
}

// A point's plane-regularized covariance (docs/lidar.md, eq. 4.17): eigenvalues epsilon
// along the normal, 1 along the plane.
Eigen::Matrix3d PlaneCovariance(const Eigen::Vector3d& normal, double epsilon) {
  return Eigen::Matrix3d::Identity() - (1.0 - epsilon) * normal * normal.transpose();
}

// Generalized-ICP at T (eqs. 4.17-4.18): d = T p - q with the information
// M = 2 epsilon (C_q + R C_p R^T)^-1, scaled so that sqrt(d^T M d) is the point-to-plane
// distance in metres for coplanar neighbourhoods (the robust loss and the statistics use it);
// dd/d[rho; phi] = [I, -(T p - c)^] for the left perturbation about the centre c (eq. 4.7c).
NormalEquations LinearizeGeneralized(const Eigen::Matrix3Xd& source,
                                     const SurfaceNormals& source_normals, const IcpTarget& target,
                                     const geometry::Pose3d& T, const Eigen::Vector3d& centre,
                                     const IcpOptions& setting, std::vector<int>* matches_io) {
  const Eigen::Matrix3d R = T.R();
  const double epsilon = setting.gicp_epsilon;
  return SumOverMatchedPlanes(
      source, target, T, setting, matches_io,
      [&](NormalEquations& eq, int64_t i, int match, const Eigen::Vector3d& p) {
        if (source_normals.planarity(i) <= 0.0) return;
        const Eigen::Vector3d d = p - target.points().col(match);
        const Eigen::Matrix3d C =
            PlaneCovariance(target.normals().normals.col(match), epsilon) +
            R * PlaneCovariance(source_normals.normals.col(i), epsilon) * R.transpose();
        const Eigen::Matrix3d M = 2.0 * epsilon * C.inverse();
        const double r = std::sqrt(std::max(d.dot(M * d), 0.0));
        Eigen::Matrix<double, 3, 6> J;
        J.leftCols<3>().setIdentity();
        J.rightCols<3>() = -geometry::Hat(Eigen::Vector3d(p - centre));
        const double w = setting.robust.Weight(r);
        eq.H.noalias() += w * J.transpose() * M * J;
        eq.g.noalias() += w * J.transpose() * (M * d);
        eq.weighted_squared_residuals += w * r * r;
        eq.squared_residuals += r * r;
        ++eq.count;
      });
}

// Point-to-point correspondences at T with IRLS weights of the point distance.
void CollectPointPairs(const Eigen::Matrix3Xd& source, const IcpTarget& target,
                       const geometry::Pose3d& T, const IcpOptions& setting,
                       std::vector<WeightedPair>* pairs) {
  const Eigen::Matrix3d R = T.R();
  pairs->clear();
  Neighbor nearest;
  for (Eigen::Index i = 0; i < source.cols(); ++i) {
    const Eigen::Vector3d p = R * source.col(i) + T.p;
    if (!target.tree().Nearest(p, setting.max_correspondence_m, &nearest)) continue;
    const double distance = std::sqrt(nearest.squared_distance_m2);
    pairs->push_back(WeightedPair{source.col(i), target.points().col(nearest.index),
                                  setting.robust.Weight(distance)});
  }
}

// Point-to-point normal equations at T for the covariance: r = T p - q (3 rows) with
// dr/d[rho; phi] = [I, -(T p - c)^] about the centre c (eq. 4.7c).
NormalEquations LinearizePointPairs(const std::vector<WeightedPair>& pairs,
                                    const geometry::Pose3d& T, const Eigen::Vector3d& centre) {
  const Eigen::Matrix3d R = T.R();
  NormalEquations eq;
  Eigen::Matrix<double, 3, 6> J;
  J.leftCols<3>().setIdentity();
  for (const WeightedPair& pair : pairs) {
    const Eigen::Vector3d p = R * pair.source + T.p;
    const Eigen::Vector3d r = p - pair.target;
    J.rightCols<3>() = -geometry::Hat(Eigen::Vector3d(p - centre));
    eq.H.noalias() += pair.weight * J.transpose() * J;
    eq.g.noalias() += pair.weight * J.transpose() * r;
    eq.weighted_squared_residuals += pair.weight * r.squaredNorm();
    eq.squared_residuals += r.squaredNorm();
    ++eq.count;
  }
  eq.residual_dimension = 3;
  return eq;
}

void RequireConstrained(const NormalEquations& eq) {
  const Eigen::Matrix<double, 6, 1> l =
      Eigen::SelfAdjointEigenSolver<Matrix6d>(eq.H, Eigen::EigenvaluesOnly).eigenvalues();
  if (!(l(0) > kDegenerateEigenRatio * l(5))) {
    std::ostringstream message;
    message << "ICP is degenerate: the " << eq.count
            << " correspondences leave a direction of motion unconstrained (eigenvalues of "
               "J^T W J: "
            << l.transpose() << ")";
    throw Error(message.str());
  }
}

// The directions of motion the correspondences of `matches` at T leave unconstrained
// (docs/lidar.md, "Degeneracy"), as unit columns of the centred perturbation [rho; phi]. For
// each eigen-direction v of sum n n^T, and each eigen-axis u of sum a a^T with the unit lever
// a = (p - c) x n / |p - c|, over the correspondences whose target is a plane
// (kCountedPlanarity), it counts those with |n . v| (|a . u|) of at least kAlignedCosine; fewer
// than max(6, count / 200) of them leave it weak. A corridor's along-track
// translation has none: normals estimated from noise or corners carry a little of it, enough
// for J^T W J to look regular (and its covariance to claim millimetres), never a normal within
// 60 degrees of the track.
Eigen::Matrix<double, 6, Eigen::Dynamic> FindWeakDirections(
    const Eigen::Matrix3Xd& source, const IcpTarget& target, const geometry::Pose3d& T,
    const Eigen::Vector3d& centre, const IcpOptions& setting, const std::vector<int>& matches) {
  const Eigen::Matrix3d R = T.R();
  const Eigen::VectorXd& planarity = target.normals().planarity;
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> normals_and_levers;
  Eigen::Matrix3d normal_scatter = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d lever_scatter = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < matches.size(); ++i) {
    const int match = matches[i];
    if (match < 0 || !CarriesPlane(planarity(match), setting) ||
        planarity(match) < kCountedPlanarity) {
      continue;
    }
    const Eigen::Vector3d n = target.normals().normals.col(match);
    const Eigen::Vector3d arm = R * source.col(static_cast<Eigen::Index>(i)) + T.p - centre;
    const double arm_m = arm.norm();
    const Eigen::Vector3d lever =
        arm_m > 0.0 ? Eigen::Vector3d(arm.cross(n) / arm_m) : Eigen::Vector3d::Zero();
    normals_and_levers.emplace_back(n, lever);
    normal_scatter.noalias() += n * n.transpose();
    lever_scatter.noalias() += lever * lever.transpose();
  }
  const int64_t needed = std::max<int64_t>(
      kMinCorrespondences, static_cast<int64_t>(normals_and_levers.size()) / kAlignedShareDivisor);
  std::vector<Vector6d> weak;
  for (const bool rotation : {false, true}) {
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(rotation ? lever_scatter
                                                                        : normal_scatter);
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d v = eigen.eigenvectors().col(k);
      int64_t aligned = 0;
      for (const auto& [n, lever] : normals_and_levers) {
        aligned += std::abs((rotation ? lever : n).dot(v)) >= kAlignedCosine;
      }
      if (aligned >= needed) continue;
      Vector6d direction = Vector6d::Zero();
      // Signed so that its largest component is positive: the same axis reads the same.
      Eigen::Index largest = 0;
      v.cwiseAbs().maxCoeff(&largest);
      direction.segment<3>(rotation ? 3 : 0) = v(largest) < 0.0 ? Eigen::Vector3d(-v) : v;
      weak.push_back(direction);
    }
  }
  Eigen::Matrix<double, 6, Eigen::Dynamic> out(6, static_cast<Eigen::Index>(weak.size()));
  for (size_t k = 0; k < weak.size(); ++k) out.col(static_cast<Eigen::Index>(k)) = weak[k];
  return out;
}

// An orthonormal basis of the directions orthogonal to the columns of `weak` (themselves
// orthonormal: eigenvectors of one block each).
Eigen::Matrix<double, 6, Eigen::Dynamic> ConstrainedBasis(
    const Eigen::Matrix<double, 6, Eigen::Dynamic>& weak) {
  const Matrix6d projector = Matrix6d::Identity() - weak * weak.transpose();
  const Eigen::SelfAdjointEigenSolver<Matrix6d> eigen(projector);
  const Eigen::Index kept = 6 - weak.cols();
  return eigen.eigenvectors().rightCols(kept);  // eigenvalue 1, ascending order
}

// H^-1, or with weak directions the inverse on the others, zero along the weak ones.
Matrix6d ConstrainedInverse(const Matrix6d& H,
                            const Eigen::Matrix<double, 6, Eigen::Dynamic>& weak) {
  if (weak.cols() == 0) return H.inverse();
  if (weak.cols() == 6) return Matrix6d::Zero();
  const Eigen::Matrix<double, 6, Eigen::Dynamic> P = ConstrainedBasis(weak);
  return P * (P.transpose() * H * P).inverse() * P.transpose();
}

// The Gauss-Newton step of eq. (4.11), in the directions `weak` leaves (none: all of them);
// LDLT on the system, no explicit inverse.
Vector6d ConstrainedStep(const NormalEquations& eq,
                         const Eigen::Matrix<double, 6, Eigen::Dynamic>& weak) {
  if (weak.cols() == 0) return -eq.H.ldlt().solve(eq.g);
  if (weak.cols() == 6) return Vector6d::Zero();  // every motion held: no plane seen at all
  const Eigen::Matrix<double, 6, Eigen::Dynamic> P = ConstrainedBasis(weak);
  const Eigen::MatrixXd reduced = P.transpose() * eq.H * P;
  return -P * reduced.ldlt().solve(P.transpose() * eq.g);
}

// The error for weak directions under IcpDegenerate::kRefuse.
std::string DescribeWeak(const Eigen::Matrix<double, 6, Eigen::Dynamic>& weak, int count) {
  std::ostringstream message;
  message.precision(2);
  message << std::fixed << "ICP is degenerate: of the " << count
          << " correspondences, too few have a normal within 60 degrees of";
  for (Eigen::Index k = 0; k < weak.cols(); ++k) {
    const bool rotation = weak.col(k).head<3>().isZero();
    const Eigen::Vector3d v = weak.col(k).segment<3>(rotation ? 3 : 0);
    message << (k > 0 ? "," : "")
            << (rotation ? " the rotation about (" : " the translation along (") << v.x() << ", "
            << v.y() << ", " << v.z() << ")";
  }
  message << " in the target frame (a corridor or tunnel leaves its axis so): that motion is "
             "not determined by the clouds (IcpOptions::degenerate = kHoldGuess keeps the guess's)";
  return message.str();
}

void RequireEnough(int count, const IcpOptions& setting, Eigen::Index source_size) {
  if (count < kMinCorrespondences) {
    throw Error("ICP found only " + std::to_string(count) + " correspondences for " +
                std::to_string(source_size) + " source points within max_correspondence_m = " +
                std::to_string(setting.max_correspondence_m) + " m (need " +
                std::to_string(kMinCorrespondences) +
                "): the clouds do not overlap at the initial guess");
  }
}

// Eqs. (4.14)-(4.15): Cov = sigma^2 H^-1 with sigma^2 estimated from the weighted residuals
// when not given; for point-to-plane with the source range noise given, eq. (4.16) instead
// (only LinearizePointToPlane sums eq.propagated).
void FillStatistics(const NormalEquations& eq, const Eigen::Matrix<double, 6, Eigen::Dynamic>& weak,
                    const Eigen::Vector3d& centre, const IcpOptions& setting,
                    Eigen::Index source_size, IcpResult* result) {
  result->num_correspondences = eq.count;
  result->fitness = source_size > 0 ? static_cast<double>(eq.count) / source_size : 0.0;
  const int num_residuals = eq.count * eq.residual_dimension;
  result->inlier_rmse_m = eq.count > 0 ? std::sqrt(eq.squared_residuals / eq.count) : 0.0;
  double sigma = setting.residual_sigma_m;
  if (!(sigma > 0.0)) {
    sigma =
        num_residuals > 6 ? std::sqrt(eq.weighted_squared_residuals / (num_residuals - 6)) : 0.0;
  }
  result->residual_sigma_m = sigma;
  const Matrix6d H_inverse = ConstrainedInverse(eq.H, weak);
  Matrix6d covariance_centred;
  if (setting.method == IcpMethod::kPointToPlane && setting.source_range_sigma_m > 0.0) {
    covariance_centred = H_inverse * eq.propagated * H_inverse;  // eq. (4.16)
  } else {
    covariance_centred = sigma * sigma * H_inverse;  // eq. (4.14)
  }
  // eq. (4.11c): delta = A delta_c with A = [I, c^; 0, I].
  Matrix6d A = Matrix6d::Identity();
  A.topRightCorner<3, 3>() = geometry::Hat(centre);
  result->covariance = A * covariance_centred * A.transpose();
}

// T <- Exp(delta_c) applied about the centre c, Tc Exp(delta_c) Tc^-1 T (eq. 4.11c).
geometry::Pose3d StepAbout(const Vector6d& delta_c, const Eigen::Vector3d& centre,
                           const geometry::Pose3d& T) {
  const geometry::Pose3d step = geometry::ExpSE3(delta_c);
  geometry::Pose3d out(step.q * T.q, step.q * (T.p - centre) + step.p + centre);
  out.q.normalize();
  return out;
}

}  // namespace

IcpMethod ParseIcpMethod(const std::string& name) {
  if (name == "point_to_point") return IcpMethod::kPointToPoint;
  if (name == "point_to_plane") return IcpMethod::kPointToPlane;
  if (name == "gicp") return IcpMethod::kGeneralized;
  throw Error("unknown ICP method '" + name +
              "' (expected point_to_point, point_to_plane or gicp)");
}

const char* IcpMethodName(IcpMethod method) {
  switch (method) {
    case IcpMethod::kPointToPoint:
      return "point_to_point";
    case IcpMethod::kPointToPlane:
      return "point_to_plane";
    case IcpMethod::kGeneralized:
      return "gicp";
  }
  return "point_to_plane";
}

geometry::Pose3d AlignCorrespondences(const Eigen::Matrix3Xd& source,
                                      const Eigen::Matrix3Xd& target,
                                      const Eigen::VectorXd& weights) {
  if (source.cols() != target.cols()) {
    throw Error("AlignCorrespondences: " + std::to_string(source.cols()) + " source points but " +
                std::to_string(target.cols()) + " target points");
  }
  if (weights.size() != 0 && weights.size() != source.cols()) {
    throw Error("AlignCorrespondences: " + std::to_string(weights.size()) + " weights for " +
                std::to_string(source.cols()) + " pairs");
  }
  RequireFinite(source, "AlignCorrespondences: the source");
  RequireFinite(target, "AlignCorrespondences: the target");
  if (weights.size() != 0 && (!weights.allFinite() || (weights.array() < 0.0).any())) {
    throw Error("AlignCorrespondences: weights must be finite and non-negative");
  }
  std::vector<WeightedPair> pairs(static_cast<size_t>(source.cols()));
  for (Eigen::Index i = 0; i < source.cols(); ++i) {
    pairs[i] = WeightedPair{source.col(i), target.col(i), weights.size() ? weights(i) : 1.0};
  }
  return SolveRigid(pairs);
}

IcpTarget::IcpTarget(Eigen::Matrix3Xd points, TargetNormals normals,
                     const NormalEstimationOptions& normal_setting, int num_threads)
    : tree_(std::move(points), num_threads), mode_(normals), normal_setting_(normal_setting) {
  if (mode_ == TargetNormals::kAll) {
    normals_ = EstimateNormals(tree_, normal_setting_, num_threads);
  } else if (mode_ == TargetNormals::kOnDemand) {
    if (normal_setting_.num_neighbors < 3) {
      throw Error("IcpTarget: num_neighbors must be at least 3, got " +
                  std::to_string(normal_setting_.num_neighbors));
    }
    normals_.normals.setZero(3, tree_.size());
    normals_.planarity.setZero(tree_.size());
    prepared_.assign(static_cast<size_t>(tree_.size()), 0);
  }
}

void IcpTarget::PrepareNormals(const std::vector<int>& indices, int num_threads) const {
  // Checked before any point is marked, so that a refused call leaves the cache as it was.
  for (const int index : indices) {
    if (index >= tree_.size()) {
      throw Error("IcpTarget::PrepareNormals: point index " + std::to_string(index) +
                  " is out of range for a target of " + std::to_string(tree_.size()) +
                  " points (expected below " + std::to_string(tree_.size()) +
                  ", or negative to skip)");
    }
  }
  if (mode_ != TargetNormals::kOnDemand) return;
  std::lock_guard<std::mutex> lock(*mutex_);
  std::vector<int> missing;
  for (const int index : indices) {
    if (index < 0 || prepared_[static_cast<size_t>(index)] != 0) continue;
    prepared_[static_cast<size_t>(index)] = 2;  // pending: de-duplicates `missing`
    missing.push_back(index);
  }
  const auto compute = [&](int64_t begin, int64_t end, int /*chunk*/) {
    Eigen::Vector3d normal;
    double planarity = 0.0;
    for (int64_t k = begin; k < end; ++k) {
      const int index = missing[static_cast<size_t>(k)];
      if (EstimateNormal(tree_, index, normal_setting_, &normal, &planarity)) {
        normals_.normals.col(index) = normal;
        normals_.planarity(index) = planarity;
      }
    }
  };
  try {
    ParallelFor(0, static_cast<int64_t>(missing.size()), num_threads, compute);
  } catch (...) {
    // The pending points stay unprepared, for the next call to compute.
    for (const int index : missing) prepared_[static_cast<size_t>(index)] = 0;
    throw;
  }
  for (const int index : missing) prepared_[static_cast<size_t>(index)] = 1;
}

IcpResult AlignIcp(const Eigen::Matrix3Xd& source, const IcpTarget& target,
                   const geometry::Pose3d& T_target_source_guess, const IcpOptions& setting) {
  RequireFinite(source, "ICP source");
  if (!T_target_source_guess.p.allFinite() || !T_target_source_guess.q.coeffs().allFinite()) {
    throw Error("ICP initial guess is not finite");
  }
  if (!(setting.max_correspondence_m > 0.0) || setting.convergence.max_iterations < 1) {
    throw Error("ICP setting: max_correspondence_m must be > 0 and max_iterations >= 1");
  }
  if (setting.robust.loss != factors::RobustLoss::kNone && !(setting.robust.scale_m > 0.0)) {
    throw Error("ICP setting: the robust loss scale must be > 0");
  }
  const bool point_to_plane = setting.method == IcpMethod::kPointToPlane;
  const bool generalized = setting.method == IcpMethod::kGeneralized;
  if ((point_to_plane || generalized) && !target.has_normals()) {
    throw Error("point-to-plane ICP and GICP need a target prepared with normals");
  }
  if (generalized && !(setting.gicp_epsilon > 0.0 && setting.gicp_epsilon <= 1.0)) {
    throw Error("ICP setting: gicp_epsilon must lie in (0, 1]");
  }
  // GICP's source covariances come from the source's own neighbourhoods.
  const SurfaceNormals source_normals =
      generalized ? EstimateNormals(KdTree(source), setting.source_normals, setting.num_threads)
                  : SurfaceNormals();

  IcpResult result;
  geometry::Pose3d T = T_target_source_guess;
  T.q.normalize();
  // The perturbation is linearized about the guessed place of the source points' centroid
  // (eq. 4.7c): about an origin far from the points (the target's, which a long drive leaves
  // kilometres behind, or the source's own for clouds in a map or ENU frame), a tilt and a
  // translation move them almost alike, J^T W J is conditioned by the squared distance and
  // the degeneracy test fires on a well-constrained pair.
  const Eigen::Vector3d centre = T * Eigen::Vector3d(source.rowwise().mean());
  NormalEquations last;
  // Weak directions of the last linearization, and where it was taken. kRefuse and kHoldGuess
  // need them at every iteration; kReport only at the end.
  Eigen::Matrix<double, 6, Eigen::Dynamic> weak(6, 0);
  const Eigen::Matrix<double, 6, Eigen::Dynamic> none(6, 0);
  const bool weak_every_iteration = setting.degenerate != IcpDegenerate::kReport;
  geometry::Pose3d linearized_at = T;
  std::vector<int> matches;  // of the last point-to-plane or GICP iteration
  std::vector<WeightedPair> pairs;
  if (!point_to_plane && !generalized) pairs.reserve(static_cast<size_t>(source.cols()));

  for (int iteration = 1; iteration <= setting.convergence.max_iterations; ++iteration) {
    result.iterations = iteration;
    double step_translation_m = 0.0;
    double step_rotation_rad = 0.0;
    if (point_to_plane || generalized) {
      last = generalized ? LinearizeGeneralized(source, source_normals, target, T, centre, setting,
                                                &matches)
                         : LinearizePointToPlane(source, target, T, centre, setting, &matches);
      RequireEnough(last.count, setting, source.cols());
      RequireConstrained(last);
      linearized_at = T;
      if (weak_every_iteration) {
        weak = FindWeakDirections(source, target, T, centre, setting, matches);
        if (weak.cols() > 0 && setting.degenerate == IcpDegenerate::kRefuse) {
          throw Error(DescribeWeak(weak, last.count));
        }
      }
      const Vector6d delta_c =
          ConstrainedStep(last, setting.degenerate == IcpDegenerate::kHoldGuess ? weak : none);
      T = StepAbout(delta_c, centre, T);
      step_translation_m = delta_c.head<3>().norm();
      step_rotation_rad = delta_c.tail<3>().norm();
    } else {
      CollectPointPairs(source, target, T, setting, &pairs);
      RequireEnough(static_cast<int>(pairs.size()), setting, source.cols());
      const geometry::Pose3d T_new = SolveRigid(pairs);
      step_translation_m = (T_new.p - T.p).norm();
      step_rotation_rad = geometry::AngularDistance(T.q, T_new.q);
      T = T_new;
      last = LinearizePointPairs(pairs, T, centre);
      RequireConstrained(last);
    }
    if (step_translation_m < setting.convergence.translation_m &&
        step_rotation_rad < setting.convergence.rotation_rad) {
      result.converged = true;
      break;
    }
  }
  // The statistics use the last linearization; after convergence it is one step (below the
  // tolerances) from the returned pose, which changes nothing at the noise level.
  result.T_target_source = T;
  if (!weak_every_iteration && (point_to_plane || generalized)) {
    weak = FindWeakDirections(source, target, linearized_at, centre, setting, matches);
  }
  FillStatistics(last, setting.degenerate == IcpDegenerate::kHoldGuess ? weak : none, centre,
                 setting, source.cols(), &result);
  for (Eigen::Index k = 0; k < weak.cols(); ++k) {
    const bool rotation = weak.col(k).head<3>().isZero();
    (rotation ? result.weak_rotation_axes : result.weak_translations)
        .push_back(weak.col(k).segment<3>(rotation ? 3 : 0));
  }
  return result;
}

}  // namespace lidar
}  // namespace autocal
