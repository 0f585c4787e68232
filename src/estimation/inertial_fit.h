#pragma once

// Step 5 of the LiDAR-IMU initializer (docs/initialization.md, eq. I3-I7): the inertial fit
// of the lever arm, accelerometer bias, gravity and per-keyframe velocities to IMU
// preintegration between keyframes placed on the LiDAR odometry.

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "autocal/estimation/calibration_initializer.h"
#include "autocal/estimation/initialization.h"
#include "autocal/geometry/se3.h"
#include "autocal/sensors/measurements.h"

namespace autocal {
namespace estimation {
namespace internal {

// The keyframes of steps 5 and 6: sweep index, IMU time, odometry pose at that instant.
struct KeyframeSlot {
  int sweep = 0;
  int64_t t_ns = 0;        // IMU clock
  geometry::Pose3d T_O_L;  // at LiDAR time t_ns - offset
};

// Step 5: the lever arm p_I_L, the accelerometer bias b_a, gravity in O, a rotation theta
// of R_I_L about the IMU's vertical u and one velocity v_k (in O) per keyframe, from IMU
// preintegration between consecutive keyframes with the IMU positions and rotations
// p_k = p_O_L,k - R_k p_I_L, R_k = R_O_L,k R_I_L^T Exp(-theta u) taken from odometry
// (docs/initialization.md, eq. I3-I7). Linear in x = [p_I_L, b_a, g_O, theta, v_0 ..
// v_{N-1}] to first order in theta; solved by normal equations, with Huber re-weighting of
// the odometry positions (a sweep where the odometry slipped, e.g. along a featureless
// street, is down-weighted). Lever-arm axes and theta whose posterior standard deviation
// exceeds the options' limits are held (at the prior, at zero). Outputs the IMU positions p_O_I,k
// integrated from the fitted velocities (eq. I7), which bridge such slips.
class InertialFit {
 public:
  InertialFit(const sensors::ImuSamples& imu, const std::vector<KeyframeSlot>& slots,
              const CalibrationInitializerOptions& options, const Eigen::Matrix3d& R_I_L,
              const Eigen::Vector3d& b_g, const Eigen::Matrix3d& R_O_I_rest,
              const Eigen::Vector3d& f_rest, const Eigen::Vector3d& up_I, const StillStart* rest);

  void Solve(InertialAlignment* fit, std::vector<Eigen::Vector3d>* p_O_I,
             std::vector<Eigen::Vector3d>* v_O_I);

 private:
  static constexpr int kP = 0, kBa = 3, kG = 6, kTheta = 9, kV = 10;
  static int VelocityIndex(int k) { return kV + 3 * k; }
  // One block row r = sum_c A_c x_c - b, whitened by 1/sigma.
  struct Row {
    std::vector<std::pair<int, Eigen::MatrixXd>> blocks;
    Eigen::Vector3d b;
    double sigma;
  };
  struct Delta {
    double dt_s;
    Eigen::Vector3d dp;
    Eigen::Matrix3d d_p_d_ba;
  };

  static Eigen::Vector3d Residual(const Row& row, const Eigen::VectorXd& x);
  void Build(const std::vector<int>& index, const Eigen::VectorXd& held_x, int size,
             Eigen::SparseMatrix<double>* H, Eigen::VectorXd* g) const;
  std::vector<int> AllFree() const;
  Eigen::VectorXd SolveHolding(const Eigen::Matrix<bool, 3, 1>& hold, bool hold_theta) const;

  const CalibrationInitializerOptions& options_;
  int n_;
  int dim_;
  std::vector<Row> rows_;
  std::vector<double> weights_;
  std::vector<size_t> position_rows_;
  std::vector<Eigen::Matrix3d> R_;
  std::vector<Delta> deltas_;
  Eigen::Vector3d p_O_I_0_;
};

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
