#include "autocal/factors/point_to_sweep_plane_group_factor.h"

#include <array>
#include <cmath>
#include <string>
#include <utility>

#include "autocal/common/error.h"

namespace autocal {
namespace factors {
namespace {

constexpr std::array<int, 9> kBlockSizes = {4, 3, 3, 4, 3, 3, 4, 3, 1};
static_assert(4 + 3 + 3 + 4 + 3 + 3 + 4 + 3 + 1 == PointToSweepPlaneGroupFactor::kAmbientSize,
              "kAmbientSize is the blocks' sizes");

}  // namespace

namespace {

bool SameMotion(const PointMotion& a, const PointMotion& b) {
  return a.dt_s == b.dt_s && a.delta_q.coeffs() == b.delta_q.coeffs() && a.delta_v == b.delta_v &&
         a.delta_p == b.delta_p && a.omega_rad_s == b.omega_rad_s;
}

// The points' terms, with one plane side per run of points with the same plane motion.
std::pair<std::vector<PointToSweepPlaneFactor::Terms>, std::vector<PointToSweepPlaneFactor::Side>>
TermsOf(const std::vector<PointToSweepPlaneMeasurement>& points, const Eigen::Vector3d& g_W) {
  std::vector<PointToSweepPlaneFactor::Terms> terms;
  std::vector<PointToSweepPlaneFactor::Side> plane_sides;
  terms.reserve(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    if (i == 0 || !SameMotion(points[i].plane_motion, points[i - 1].plane_motion)) {
      plane_sides.emplace_back(points[i].plane_motion, g_W);
    }
    terms.emplace_back(points[i], g_W, static_cast<uint32_t>(plane_sides.size() - 1));
  }
  return {std::move(terms), std::move(plane_sides)};
}

}  // namespace

PointToSweepPlaneGroupFactor::PointToSweepPlaneGroupFactor(
    const std::vector<PointToSweepPlaneMeasurement>& points, const Eigen::Vector3d& g_W,
    const LossOptions& loss)
    : PointToSweepPlaneGroupFactor(TermsOf(points, g_W), loss) {}

PointToSweepPlaneGroupFactor::PointToSweepPlaneGroupFactor(TermsAndSides terms,
                                                           const LossOptions& loss)
    : PointToSweepPlaneGroupFactor(std::move(terms.first), std::move(terms.second), loss) {}

PointToSweepPlaneGroupFactor::PointToSweepPlaneGroupFactor(
    std::vector<PointToSweepPlaneFactor::Terms> points,
    std::vector<PointToSweepPlaneFactor::Side> plane_sides, const LossOptions& loss)
    : points_(std::move(points)),
      plane_sides_(std::move(plane_sides)),
      loss_(MakeLossFunction(loss)) {
  if (points_.empty()) throw Error("PointToSweepPlaneGroupFactor: no points");
  for (size_t i = 0; i < points_.size(); ++i) {
    if (points_[i].plane_side() >= plane_sides_.size()) {
      throw Error("PointToSweepPlaneGroupFactor: point " + std::to_string(i) +
                  " refers to plane side " + std::to_string(points_[i].plane_side()) + " of " +
                  std::to_string(plane_sides_.size()));
    }
  }
  set_num_residuals(static_cast<int>(points_.size()));
  for (int size : kBlockSizes) mutable_parameter_block_sizes()->push_back(size);
}

std::vector<PointToSweepPlaneFactor::PlaneFrame> PointToSweepPlaneGroupFactor::PlaneFrames(
    const PointToSweepPlaneFactor::Frame& frame) const {
  std::vector<PointToSweepPlaneFactor::PlaneFrame> planes;
  planes.reserve(plane_sides_.size());
  for (const PointToSweepPlaneFactor::Side& side : plane_sides_) planes.emplace_back(frame, side);
  return planes;
}

namespace {

// Eq. P9: row r of a point becomes sign(r) sqrt(rho(r^2)); returns the factor d r~/dr for its
// Jacobian, rho' |r| / sqrt(rho), which tends to rho'(0) = 1 as r -> 0.
double ApplyLoss(const ceres::LossFunction& loss, double* residual) {
  const double r = *residual;
  double rho[3];
  loss.Evaluate(r * r, rho);
  const double root = std::sqrt(rho[0]);
  *residual = std::copysign(root, r);
  return root > 0.0 ? rho[1] * std::abs(r) / root : rho[1];
}

}  // namespace

bool PointToSweepPlaneGroupFactor::Evaluate(double const* const* parameters, double* residuals,
                                            double** jacobians) const {
  // The rotations and lifts every point shares, once per evaluation (Eq. P8).
  const PointToSweepPlaneFactor::Frame frame(parameters);
  const std::vector<PointToSweepPlaneFactor::PlaneFrame> planes = PlaneFrames(frame);
  // Row i of each row-major n x size Jacobian is the one-row Jacobian of point i.
  std::array<double*, kBlockSizes.size()> row_jacobians;
  for (size_t i = 0; i < points_.size(); ++i) {
    double** point_jacobians = nullptr;
    if (jacobians != nullptr) {
      for (size_t b = 0; b < kBlockSizes.size(); ++b) {
        row_jacobians[b] = jacobians[b] == nullptr
                               ? nullptr
                               : jacobians[b] + i * static_cast<size_t>(kBlockSizes[b]);
      }
      point_jacobians = row_jacobians.data();
    }
    const PointToSweepPlaneFactor::Terms& point = points_[i];
    point.Evaluate(frame, planes[point.plane_side()], &residuals[i], point_jacobians);
    if (!loss_) continue;
    const double scale = ApplyLoss(*loss_, &residuals[i]);
    if (point_jacobians == nullptr) continue;
    for (size_t b = 0; b < kBlockSizes.size(); ++b) {
      if (point_jacobians[b] == nullptr) continue;
      for (int c = 0; c < kBlockSizes[b]; ++c) point_jacobians[b][c] *= scale;
    }
  }
  return true;
}

bool PointToSweepPlaneGroupFactor::EvaluateTangent(double const* const* parameters,
                                                   double* residuals, double* jacobian) const {
  const PointToSweepPlaneFactor::Frame frame(parameters);
  const std::vector<PointToSweepPlaneFactor::PlaneFrame> planes = PlaneFrames(frame);
  const size_t n = points_.size();
  for (size_t i = 0; i < n; ++i) {
    double* row = jacobian + i;
    const PointToSweepPlaneFactor::Terms& point = points_[i];
    point.EvaluateTangent(frame, planes[point.plane_side()], &residuals[i], row, n);
    if (!loss_) continue;
    const double scale = ApplyLoss(*loss_, &residuals[i]);
    for (int c = 0; c < kTangentColumns; ++c) row[static_cast<size_t>(c) * n] *= scale;
  }
  return true;
}

void PointToSweepPlaneGroupFactor::WhitenedDistances(double const* const* parameters,
                                                     double* distances) const {
  const PointToSweepPlaneFactor::Frame frame(parameters);
  const std::vector<PointToSweepPlaneFactor::PlaneFrame> planes = PlaneFrames(frame);
  for (size_t i = 0; i < points_.size(); ++i) {
    const PointToSweepPlaneFactor::Terms& point = points_[i];
    point.Evaluate(frame, planes[point.plane_side()], &distances[i], nullptr);
  }
}

}  // namespace factors
}  // namespace autocal
