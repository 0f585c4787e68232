#pragma once

// Plane fitting (docs/lidar.md §3).
//
// - The course's height model z = a + b x + c y (eq. 3.1), fitted by linear least squares
//   with a rank-revealing QR of A = [1 x y] (eq. 3.3) instead of the normal equations'
//   explicit inverse. It measures error along z only, so it degrades as the plane tilts and
//   cannot represent a vertical plane at all.
// - The total-least-squares plane (eq. 3.4): the normal is the eigenvector of the smallest
//   eigenvalue of the points' covariance; it minimizes orthogonal distances and handles
//   any orientation.
// - RANSAC ground extraction: three-point hypotheses restricted to near-horizontal
//   planes, scored by inlier count, followed by a total-least-squares refit on the inliers.

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "autocal/geometry/plane.h"

namespace autocal {
namespace lidar {

// Coefficients of z = a + b x + c y.
struct HeightPlane {
  double a = 0.0;
  double b = 0.0;
  double c = 0.0;

  double Height(double x, double y) const { return a + b * x + c * y; }
  // The same plane in normal form, normal pointing up (+z).
  geometry::Plane ToPlane() const;
};

// Least-squares fit of eq. (3.1). Throws autocal::Error with fewer than 3 points or when the
// points' xy projections are collinear (rank(A) < 3, e.g. a vertical plane seen edge-on
// along a line).
HeightPlane FitHeightPlane(const Eigen::Matrix3Xd& points);

struct PlaneFit {
  geometry::Plane plane;
  double rms_m = 0.0;      // RMS orthogonal distance of the points to the plane
  double planarity = 0.0;  // (l1 - l0) / l2 of the points' covariance
};

// Total-least-squares plane, eq. (3.4). Throws autocal::Error with fewer than 3 points or
// collinear points. The normal's sign is chosen so that normal.z() >= 0.
PlaneFit FitPlaneTotalLeastSquares(const Eigen::Matrix3Xd& points);

struct GroundExtractionOptions {
  // Points within this distance of a hypothesis are its inliers.
  double distance_threshold_m = 0.15;
  // Hypotheses whose normal is tilted more than this from +z are rejected: the road is
  // near-horizontal in the sensor frame of a car-mounted LiDAR.
  double max_tilt_deg = 20.0;
  // Upper bound on hypotheses; fewer are drawn once `confidence` is reached.
  int max_iterations = 500;
  // Stop once the probability of having drawn an all-inlier sample reaches this.
  double confidence = 0.999;
  uint64_t seed = 1;
};

struct GroundExtraction {
  geometry::Plane plane;            // least-squares refit on the inliers, normal up
  std::vector<int> inlier_indices;  // of the refitted plane, ascending
  int iterations = 0;               // hypotheses drawn
};

// Throws autocal::Error when no near-horizontal plane with at least 3 inliers is found.
GroundExtraction ExtractGround(const Eigen::Matrix3Xd& points,
                               const GroundExtractionOptions& setting = {});

}  // namespace lidar
}  // namespace autocal
