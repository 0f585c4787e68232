#include "autocal/lidar/plane_fitting.h"

#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <string>

#include "autocal/common/error.h"
#include "autocal/common/units.h"

namespace autocal {
namespace lidar {
namespace {

void RequireFinite(const Eigen::Matrix3Xd& points, const char* what) {
  if (!points.allFinite()) throw Error(std::string(what) + ": a point has a non-finite coordinate");
}

}  // namespace

geometry::Plane HeightPlane::ToPlane() const {
  // z = a + b x + c y  <=>  (-b, -c, 1) . p - a = 0.
  const Eigen::Vector3d n(-b, -c, 1.0);
  const double norm = n.norm();
  return geometry::Plane{n / norm, -a / norm};
}

HeightPlane FitHeightPlane(const Eigen::Matrix3Xd& points) {
  const Eigen::Index n = points.cols();
  if (n < 3) {
    throw Error("FitHeightPlane: need at least 3 points, got " + std::to_string(n));
  }
  RequireFinite(points, "FitHeightPlane");
  // Centring x and y keeps the columns of A (eq. 3.3) of comparable size, so the QR
  // factorization stays well conditioned far from the origin; a is shifted back below.
  const Eigen::Vector2d mean_xy = points.topRows<2>().rowwise().mean();
  Eigen::MatrixX3d A(n, 3);
  A.col(0).setOnes();
  A.col(1) = (points.row(0).array() - mean_xy.x()).transpose();
  A.col(2) = (points.row(1).array() - mean_xy.y()).transpose();
  const Eigen::VectorXd z = points.row(2).transpose();
  Eigen::ColPivHouseholderQR<Eigen::MatrixX3d> qr(A);
  qr.setThreshold(1e-10);
  if (qr.rank() < 3) {
    throw Error(
        "FitHeightPlane: the points' xy projections are collinear, z = a + b x + c y is "
        "undetermined (use FitPlaneTotalLeastSquares for vertical planes)");
  }
  const Eigen::Vector3d x = qr.solve(z);
  HeightPlane plane;
  plane.b = x(1);
  plane.c = x(2);
  plane.a = x(0) - plane.b * mean_xy.x() - plane.c * mean_xy.y();
  return plane;
}

PlaneFit FitPlaneTotalLeastSquares(const Eigen::Matrix3Xd& points) {
  const Eigen::Index n = points.cols();
  if (n < 3) {
    throw Error("FitPlaneTotalLeastSquares: need at least 3 points, got " + std::to_string(n));
  }
  RequireFinite(points, "FitPlaneTotalLeastSquares");
  const Eigen::Vector3d mean = points.rowwise().mean();
  const Eigen::Matrix3Xd centred = points.colwise() - mean;
  const Eigen::Matrix3d covariance = centred * centred.transpose() / static_cast<double>(n);
  // The iterative solver here (not computeDirect): one fit per call, accuracy first.
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(covariance);
  const Eigen::Vector3d l = solver.eigenvalues().cwiseMax(0.0);
  if (!(l(1) > 1e-12 * l(2)) || !(l(2) > 0.0)) {
    throw Error("FitPlaneTotalLeastSquares: the points are collinear or coincident, no plane");
  }
  PlaneFit fit;
  Eigen::Vector3d normal = solver.eigenvectors().col(0).normalized();
  if (normal.z() < 0.0) normal = -normal;
  fit.plane.normal = normal;
  fit.plane.d = -normal.dot(mean);
  fit.rms_m = std::sqrt(l(0));
  fit.planarity = (l(1) - l(0)) / l(2);
  return fit;
}

GroundExtraction ExtractGround(const Eigen::Matrix3Xd& points,
                               const GroundExtractionOptions& setting) {
  const int n = static_cast<int>(points.cols());
  if (n < 3) throw Error("ExtractGround: need at least 3 points, got " + std::to_string(n));
  if (!(setting.distance_threshold_m > 0.0) || setting.max_iterations < 1 ||
      !(setting.confidence > 0.0 && setting.confidence < 1.0)) {
    throw Error(
        "ExtractGround: invalid setting (threshold > 0, iterations >= 1, 0 < confidence < 1)");
  }
  RequireFinite(points, "ExtractGround");
  const double min_normal_z = std::cos(setting.max_tilt_deg * kDegToRad);
  std::mt19937_64 rng(setting.seed);
  std::uniform_int_distribution<int> pick(0, n - 1);

  auto count_inliers = [&](const geometry::Plane& plane) {
    int count = 0;
    for (int i = 0; i < n; ++i) {
      count += std::abs(plane.SignedDistance(points.col(i))) <= setting.distance_threshold_m;
    }
    return count;
  };

  geometry::Plane best;
  int best_count = 0;
  int iterations = 0;
  double needed_iterations = setting.max_iterations;
  while (iterations < setting.max_iterations && iterations < needed_iterations) {
    ++iterations;
    const Eigen::Vector3d a = points.col(pick(rng));
    const Eigen::Vector3d b = points.col(pick(rng));
    const Eigen::Vector3d c = points.col(pick(rng));
    Eigen::Vector3d normal = (b - a).cross(c - a);
    const double norm = normal.norm();
    if (!(norm > 1e-9)) continue;  // repeated or collinear sample
    normal /= norm;
    if (normal.z() < 0.0) normal = -normal;
    if (normal.z() < min_normal_z) continue;
    const geometry::Plane hypothesis{normal, -normal.dot(a)};
    const int count = count_inliers(hypothesis);
    if (count > best_count) {
      best_count = count;
      best = hypothesis;
      // Standard RANSAC bound: k = log(1 - confidence) / log(1 - w^3), w the inlier ratio.
      const double w = static_cast<double>(count) / n;
      const double all_inlier = w * w * w;
      if (all_inlier >= 1.0) {
        needed_iterations = 0;
      } else if (all_inlier > 0.0) {
        needed_iterations = std::log(1.0 - setting.confidence) / std::log(1.0 - all_inlier);
      }
    }
  }
  if (best_count < 3) {
    throw Error("ExtractGround: no plane within " + std::to_string(setting.max_tilt_deg) +
                " deg of horizontal has 3 or more inliers");
  }

  auto collect = [&](const geometry::Plane& plane) {
    std::vector<int> inliers;
    inliers.reserve(static_cast<size_t>(best_count));
    for (int i = 0; i < n; ++i) {
      if (std::abs(plane.SignedDistance(points.col(i))) <= setting.distance_threshold_m) {
        inliers.push_back(i);
      }
    }
    return inliers;
  };

  // Least-squares refit: the sample plane passes exactly through three noisy points, the
  // refit averages over all of its inliers.
  std::vector<int> inliers = collect(best);
  Eigen::Matrix3Xd inlier_points(3, static_cast<Eigen::Index>(inliers.size()));
  for (size_t i = 0; i < inliers.size(); ++i) inlier_points.col(i) = points.col(inliers[i]);
  GroundExtraction out;
  out.plane = FitPlaneTotalLeastSquares(inlier_points).plane;
  out.inlier_indices = collect(out.plane);
  out.iterations = iterations;
  return out;
}

}  // namespace lidar
}  // namespace autocal
