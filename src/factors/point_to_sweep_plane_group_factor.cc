#include "autocal/factors/point_to_sweep_plane_group_factor.h"

#include <array>
#include <cmath>

#include "autocal/common/error.h"

namespace autocal {
namespace factors {
namespace {

constexpr std::array<int, 9> kBlockSizes = {4, 3, 3, 4, 3, 3, 4, 3, 1};
// First column of each block in the stacked Jacobian: the sizes of the blocks before it.
constexpr std::array<int, 9> kBlockColumns = [] {
  std::array<int, 9> columns{};
  for (size_t b = 1; b < columns.size(); ++b) columns[b] = columns[b - 1] + kBlockSizes[b - 1];
  return columns;
}();
static_assert(kBlockColumns[8] + kBlockSizes[8] == PointToSweepPlaneGroupFactor::kAmbientSize,
              "the stacked Jacobian has every block's columns");

}  // namespace

PointToSweepPlaneGroupFactor::PointToSweepPlaneGroupFactor(
    const std::vector<PointToSweepPlaneMeasurement>& points, const Eigen::Vector3d& g_W,
    const LossOptions& loss)
    : loss_(MakeLossFunction(loss)) {
  if (points.empty()) throw Error("PointToSweepPlaneGroupFactor: no points");
  points_.reserve(points.size());
  for (const PointToSweepPlaneMeasurement& m : points) {
    points_.emplace_back(m, g_W);
  }
  set_num_residuals(static_cast<int>(points.size()));
  for (int size : kBlockSizes) mutable_parameter_block_sizes()->push_back(size);
}

template <typename RowOf>
bool PointToSweepPlaneGroupFactor::EvaluateRows(double const* const* parameters, double* residuals,
                                                const RowOf& row_of, bool tangent,
                                                bool with_jacobians) const {
  // The rotations and lifts every point shares, once per evaluation (Eq. P8).
  const PointToSweepPlaneFactor::Frame frame(parameters, tangent);
  std::array<double*, kBlockSizes.size()> row_jacobians;
  for (size_t i = 0; i < points_.size(); ++i) {
    double** point_jacobians = nullptr;
    if (with_jacobians) {
      for (size_t b = 0; b < kBlockSizes.size(); ++b) row_jacobians[b] = row_of(i, b);
      point_jacobians = row_jacobians.data();
    }
    points_[i].Evaluate(frame, &residuals[i], point_jacobians);
    if (!loss_) continue;
    // Eq. P9.
    const double r = residuals[i];
    double rho[3];
    loss_->Evaluate(r * r, rho);
    const double root = std::sqrt(rho[0]);
    residuals[i] = std::copysign(root, r);
    if (point_jacobians == nullptr) continue;
    // d r~/dr = rho' |r| / sqrt(rho), which tends to rho'(0) = 1 as r -> 0.
    const double scale = root > 0.0 ? rho[1] * std::abs(r) / root : rho[1];
    for (size_t b = 0; b < kBlockSizes.size(); ++b) {
      if (point_jacobians[b] == nullptr) continue;
      for (int c = 0; c < kBlockSizes[b]; ++c) point_jacobians[b][c] *= scale;
    }
  }
  return true;
}

bool PointToSweepPlaneGroupFactor::Evaluate(double const* const* parameters, double* residuals,
                                            double** jacobians) const {
  // Row i of each row-major n x size Jacobian is the one-row Jacobian of point i.
  return EvaluateRows(
      parameters, residuals,
      [jacobians](size_t i, size_t b) -> double* {
        if (jacobians == nullptr || jacobians[b] == nullptr) return nullptr;
        return jacobians[b] + i * static_cast<size_t>(kBlockSizes[b]);
      },
      false, jacobians != nullptr);
}

bool PointToSweepPlaneGroupFactor::EvaluateStacked(double const* const* parameters,
                                                   double* residuals, double* jacobian,
                                                   bool tangent) const {
  // Row i of the stacked Jacobian holds the nine one-row Jacobians of point i side by side.
  return EvaluateRows(
      parameters, residuals,
      [jacobian](size_t i, size_t b) -> double* {
        return jacobian + i * kAmbientSize + kBlockColumns[b];
      },
      tangent, true);
}

void PointToSweepPlaneGroupFactor::WhitenedDistances(double const* const* parameters,
                                                     double* distances) const {
  const PointToSweepPlaneFactor::Frame frame(parameters);
  for (size_t i = 0; i < points_.size(); ++i) points_[i].Evaluate(frame, &distances[i], nullptr);
}

}  // namespace factors
}  // namespace autocal
