#include "autocal/factors/point_to_sweep_plane_group_factor.h"

#include <array>
#include <cmath>
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

std::vector<PointToSweepPlaneFactor::Terms> TermsOf(
    const std::vector<PointToSweepPlaneMeasurement>& points, const Eigen::Vector3d& g_W) {
  std::vector<PointToSweepPlaneFactor::Terms> terms;
  terms.reserve(points.size());
  for (const PointToSweepPlaneMeasurement& m : points) terms.emplace_back(m, g_W);
  return terms;
}

}  // namespace

PointToSweepPlaneGroupFactor::PointToSweepPlaneGroupFactor(
    const std::vector<PointToSweepPlaneMeasurement>& points, const Eigen::Vector3d& g_W,
    const LossOptions& loss)
    : PointToSweepPlaneGroupFactor(TermsOf(points, g_W), loss) {}

PointToSweepPlaneGroupFactor::PointToSweepPlaneGroupFactor(
    std::vector<PointToSweepPlaneFactor::Terms> points, const LossOptions& loss)
    : points_(std::move(points)), loss_(MakeLossFunction(loss)) {
  if (points_.empty()) throw Error("PointToSweepPlaneGroupFactor: no points");
  set_num_residuals(static_cast<int>(points_.size()));
  for (int size : kBlockSizes) mutable_parameter_block_sizes()->push_back(size);
}

std::vector<PointToSweepPlaneFactor::Terms> PointToSweepPlaneGroupFactor::ReleasePoints(
    std::unique_ptr<PointToSweepPlaneGroupFactor> factor) {
  if (factor == nullptr) return {};
  return std::move(factor->points_);
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
    points_[i].Evaluate(frame, &residuals[i], point_jacobians);
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
  const size_t n = points_.size();
  for (size_t i = 0; i < n; ++i) {
    double* row = jacobian + i;
    points_[i].EvaluateTangent(frame, &residuals[i], row, n);
    if (!loss_) continue;
    const double scale = ApplyLoss(*loss_, &residuals[i]);
    for (int c = 0; c < kTangentColumns; ++c) row[static_cast<size_t>(c) * n] *= scale;
  }
  return true;
}

void PointToSweepPlaneGroupFactor::WhitenedDistances(double const* const* parameters,
                                                     double* distances) const {
  const PointToSweepPlaneFactor::Frame frame(parameters);
  for (size_t i = 0; i < points_.size(); ++i) points_[i].Evaluate(frame, &distances[i], nullptr);
}

}  // namespace factors
}  // namespace autocal
