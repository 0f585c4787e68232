#pragma once

// The points of one sweep k paired with planes of one other sweep j (Eq. P6-P8) as ONE
// residual block: every point of the pair depends on the same nine parameter blocks, so one
// block of n rows replaces n one-row blocks, and Ceres forms J^T J from dense n x 25
// products instead of 45 tiny ones per point (docs/estimation.md, Eq. P9).
//
// Ceres applies a loss to a block's whole squared norm, so a per-point robust loss lives in
// the factor: row i is r~_i = sign(r_i) sqrt(rho(r_i^2)) (Eq. P9), whose square is the
// robust cost of the point, with Jacobian d r~_i = rho'(r_i^2) |r_i| / sqrt(rho(r_i^2)) dr_i
// (-> dr_i as r_i -> 0). The block's cost 1/2 sum r~_i^2 = 1/2 sum rho(r_i^2) is then exactly
// the cost of the one-row blocks with the loss given to Ceres.

#include <ceres/ceres.h>

#include <Eigen/Core>
#include <memory>
#include <utility>
#include <vector>

#include "autocal/factors/loss.h"
#include "autocal/factors/point_to_sweep_plane_factor.h"

namespace autocal {
namespace factors {

class PointToSweepPlaneGroupFactor final : public ceres::CostFunction {
 public:
  // Parameters as PointToSweepPlaneFactor: keyframe k (q, p, v), keyframe j (q, p, v), q_I_L,
  // p_I_L, time offset. Throws autocal::Error for an empty group or a bad loss scale.
  PointToSweepPlaneGroupFactor(const std::vector<PointToSweepPlaneMeasurement>& points,
                               const Eigen::Vector3d& g_W, const LossOptions& loss);
  // The same from the points' terms and their planes' sides, formed by the caller (no copy of
  // the measurements): point i's plane side is plane_sides[points[i].plane_side()]. Throws
  // autocal::Error for an empty group or an index out of range.
  PointToSweepPlaneGroupFactor(std::vector<PointToSweepPlaneFactor::Terms> points,
                               std::vector<PointToSweepPlaneFactor::Side> plane_sides,
                               const LossOptions& loss);

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;
  static constexpr int kAmbientSize = 28;  // the nine blocks' sizes
  // The same in the kTangentColumns independent tangent columns of
  // PointToSweepPlaneFactor::Terms::EvaluateTangent (the quaternions' right tangents; p_j's
  // columns are minus p_k's): `jacobian` is column-major, num_residuals() x kTangentColumns,
  // the layout in which J^T J is formed fastest. The ambient Jacobian of a quaternion block is
  // its columns times geometry::QuaternionMinusJacobian(q).
  static constexpr int kTangentColumns = PointToSweepPlaneFactor::Terms::kTangentColumns;
  bool EvaluateTangent(double const* const* parameters, double* residuals, double* jacobian) const;

  int num_points() const { return static_cast<int>(points_.size()); }
  const std::vector<PointToSweepPlaneFactor::Terms>& points() const { return points_; }
  const std::vector<PointToSweepPlaneFactor::Side>& plane_sides() const { return plane_sides_; }
  // The per-point robust loss (null for plain least squares).
  const ceres::LossFunction* loss() const { return loss_.get(); }
  // The whitened point-to-plane distances r_i (no loss), one per point.
  void WhitenedDistances(double const* const* parameters, double* distances) const;

 private:
  using TermsAndSides = std::pair<std::vector<PointToSweepPlaneFactor::Terms>,
                                  std::vector<PointToSweepPlaneFactor::Side>>;
  PointToSweepPlaneGroupFactor(TermsAndSides terms, const LossOptions& loss);
  // Hands a released factor's storage on for reuse (src/factors/point_group_storage.h).
  friend class PointGroupStorage;
  // Each plane side's share of an evaluation at `frame`, in plane_sides_'s order.
  std::vector<PointToSweepPlaneFactor::PlaneFrame> PlaneFrames(
      const PointToSweepPlaneFactor::Frame& frame) const;

  std::vector<PointToSweepPlaneFactor::Terms> points_;
  std::vector<PointToSweepPlaneFactor::Side> plane_sides_;
  std::unique_ptr<ceres::LossFunction> loss_;  // null for plain least squares
};

}  // namespace factors
}  // namespace autocal
