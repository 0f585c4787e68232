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

#include <memory>
#include <vector>

#include <ceres/ceres.h>
#include <Eigen/Core>

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

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;
  // The same with the Jacobians of the nine blocks side by side: `jacobian` is row-major,
  // num_residuals() x kAmbientSize (columns in the order of the blocks). With `tangent` each
  // quaternion block's four columns hold its tangent Jacobian (right perturbation) and 0; the
  // ambient one is that times geometry::QuaternionMinusJacobian(q).
  static constexpr int kAmbientSize = 28;
  bool EvaluateStacked(double const* const* parameters, double* residuals, double* jacobian,
                       bool tangent = false) const;

  int num_points() const { return static_cast<int>(points_.size()); }

  // The whitened point-to-plane distances r_i (no loss), one per point.
  void WhitenedDistances(double const* const* parameters, double* distances) const;

 private:
  // Every point's row; row_of(i, b) is where point i's Jacobian of block b goes (nullptr: not
  // wanted), asked only with_jacobians.
  template <typename RowOf>
  bool EvaluateRows(double const* const* parameters, double* residuals, const RowOf& row_of,
                    bool tangent, bool with_jacobians) const;

  std::vector<PointToSweepPlaneFactor::Terms> points_;
  std::unique_ptr<ceres::LossFunction> loss_;  // null for plain least squares
};

}  // namespace factors
}  // namespace autocal
