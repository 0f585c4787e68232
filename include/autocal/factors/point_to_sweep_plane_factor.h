#pragma once

// LiDAR point against a plane seen by another sweep (docs/estimation.md, "Point to a plane of
// another sweep").
//
// The plane n_L . x + d_L = 0 is expressed in the LiDAR frame of sweep j at its reference
// instant (point time 0), where the IMU pose is keyframe j propagated by `plane_motion`
// (Eq. P1-P3). The point p_L of sweep k is placed in W by keyframe k (Eq. P1-P3) and taken
// into that frame, T_W_Lj = T_W_Ij(t) T_I_L:
//   r = ( n_L . T_W_Lj^-1 p_W + d_L ) / sigma                                    (Eq. P6)
// The plane moves with the state and extrinsic that observed it, so a wrong calibration
// cannot be absorbed into a map built from it (as it is by a plane held fixed in W).
//
// Parameter blocks: keyframe k's q_W_I (4), p_W_I (3), v_W_I (3); keyframe j's q_W_I (4),
// p_W_I (3), v_W_I (3); q_I_L (4), p_I_L (3), time_offset_lidar_imu_s (1). Quaternions on
// the RightQuaternionManifold. Keyframes k and j must be different blocks.

#include <ceres/ceres.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>

#include "autocal/factors/point_to_plane_factor.h"
#include "autocal/geometry/plane.h"

namespace autocal {
namespace factors {

struct PointToSweepPlaneMeasurement {
  Eigen::Vector3d p_L = Eigen::Vector3d::Zero();  // the point in sweep k's LiDAR frame
  PointMotion motion;                             // keyframe k to the point's instant
  PointMotion plane_motion;                       // keyframe j to sweep j's reference instant
  geometry::Plane plane_L;                        // in sweep j's LiDAR frame at that instant
  double sigma_m = 0.02;                          // 1-sigma of the point-to-plane distance
  double offset_linearization_s = 0.0;            // offset_0 of both motions
};

class PointToSweepPlaneFactor final
    : public ceres::SizedCostFunction<1, 4, 3, 3, 4, 3, 3, 4, 3, 1> {
 public:
  // What every point of a pair of sweeps shares: the parameter blocks as rotation matrices
  // and the quaternion lifts of the tangent Jacobians (a tangent row a maps to the ambient
  // row a^T lift), computed once per evaluation of a group (Eq. P8).
  struct Frame {
    explicit Frame(double const* const* parameters);
    Eigen::Matrix3d R_k;
    Eigen::Vector3d p_k;
    Eigen::Vector3d v_k;
    Eigen::Matrix3d R_j;
    Eigen::Vector3d p_j;
    Eigen::Vector3d v_j;
    Eigen::Matrix3d R_I_L;
    Eigen::Vector3d p_I_L;
    double time_offset_s;
    Eigen::Matrix<double, 3, 4> lift_k;
    Eigen::Matrix<double, 3, 4> lift_j;
    // R_I_L times the lift: takes a row in q_I_L's left tangent (Exp(phi) q) to the block's
    // coordinates, phi = R_I_L theta.
    Eigen::Matrix<double, 3, 4> lift_I_L_left;
  };

  // One side's propagation (Eq. P1-P3) in the form the Jacobians use: the point's, from
  // keyframe k to its instant, or the plane's, from keyframe j to sweep j's reference instant.
  // The points a sweep pairs with one partner in one association share the plane's, so a
  // group keeps each distinct one once.
  struct Side {
    Side(const PointMotion& motion, const Eigen::Vector3d& g_W);
    Eigen::Matrix3d delta_R;
    Eigen::Vector3d omega_rad_s;
    Eigen::Vector3d delta_v;
    Eigen::Vector3d delta_p;
    Eigen::Vector3d gravity_velocity;  // g_W dt
    Eigen::Vector3d gravity_position;  // g_W dt^2 / 2
    double dt_s;
  };

  // What a Frame and one plane Side give every point paired with that side, once per
  // evaluation (Eq. P7 rearranged, docs/estimation.md): with B_j = dR_j, M_j = R_j B_j, the
  // point's t = B_j^T (R_j^T w - b) = M_j^T (p_W - c) - b' where, linear in the point's offset
  // change delta, c = c0 + delta c1 (the plane side's propagated position) and
  // b' = B_j^T b = b0 + delta b1.
  struct PlaneFrame {
    PlaneFrame(const Frame& frame, const Side& plane);
    Eigen::Matrix3d M_j;          // R_j dR_j
    Eigen::Matrix3d delta_R;      // dR_j
    Eigen::Vector3d omega_rad_s;  // omega_j
    Eigen::Vector3d c0, c1;       // p_j + dt_j v_j + g dt_j^2 / 2;  v_j + g dt_j
    Eigen::Vector3d b0, b1;       // p_I_L + dR_j^T dp_j;  omega_j x p_I_L + dR_j^T dv_j
    double dt_s;
  };

  // One point's terms of Eq. P1-P7 that the parameters do not change, evaluated against a
  // Frame and its plane's Side (the measurement's plane_motion, held by the caller: a group
  // keeps each distinct one once, and each point the index of its own). Plain data: a group
  // keeps its points in one array.
  class Terms {
   public:
    Terms(const PointToSweepPlaneMeasurement& measurement, const Eigen::Vector3d& g_W,
          uint32_t plane_side = 0);
    // jacobians as in PointToSweepPlaneFactor::Evaluate.
    void Evaluate(const Frame& frame, const PlaneFrame& plane, double* residual,
                  double** jacobians) const;
    // The Jacobian in the kTangentColumns independent tangent columns, column c into
    // row[c * stride]: theta_k (right tangent of q_W_I k), p_k, v_k, theta_j, v_j, theta_I_L
    // (right tangent), p_I_L, the offset. The p_j columns are minus p_k's.
    static constexpr int kTangentColumns = 22;
    void EvaluateTangent(const Frame& frame, const PlaneFrame& plane, double* residual, double* row,
                         size_t stride) const;
    // The index of the point's plane Side among its group's.
    uint32_t plane_side() const { return plane_side_; }
    void set_plane_side(uint32_t index) { plane_side_ = index; }

   private:
    // The Jacobian's rows before any lift: the quaternion blocks' right tangents, except
    // q_I_L's, given in its left tangent (Exp(phi) q); p_j's is minus p_k's.
    struct Rows {
      Eigen::Vector3d theta_k, p_k, v_k, theta_j, v_j, phi_I_L, p_I_L;
      double offset;
    };
    // The residual, and the rows when `rows` is not null: those of q_I_L, p_I_L and the offset
    // only with `calibration_rows`.
    double Core(const Frame& frame, const PlaneFrame& plane, Rows* rows,
                bool calibration_rows) const;

    Side point_;
    Eigen::Vector3d p_L_;
    Eigen::Vector3d n_L_;
    double d_L_;
    double inv_sigma_;
    double offset_linearization_s_;
    uint32_t plane_side_;
  };

  PointToSweepPlaneFactor(const PointToSweepPlaneMeasurement& measurement,
                          const Eigen::Vector3d& g_W)
      : terms_(measurement, g_W), plane_(measurement.plane_motion, g_W) {}

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

 private:
  Terms terms_;
  Side plane_;
};

// Autodiff twin (Eq. P6 written literally); the test oracle.
struct PointToSweepPlaneResidual {
  PointToSweepPlaneResidual(const PointToSweepPlaneMeasurement& measurement,
                            const Eigen::Vector3d& g_W)
      : m(measurement), g(g_W) {}

  template <typename T>
  bool operator()(const T* q_k_ptr, const T* p_k_ptr, const T* v_k_ptr, const T* q_j_ptr,
                  const T* p_j_ptr, const T* v_j_ptr, const T* q_I_L_ptr, const T* p_I_L_ptr,
                  const T* offset_ptr, T* residual) const {
    using Vec3 = Eigen::Matrix<T, 3, 1>;
    using Quat = Eigen::Quaternion<T>;
    const Quat q_I_L = Eigen::Map<const Quat>(q_I_L_ptr);
    const Vec3 p_I_L = Eigen::Map<const Vec3>(p_I_L_ptr);
    const T delta = offset_ptr[0] - T(m.offset_linearization_s);
    const PropagatedPose<T> point = PropagateKeyframe<T>(
        Quat(Eigen::Map<const Quat>(q_k_ptr)), Vec3(Eigen::Map<const Vec3>(p_k_ptr)),
        Vec3(Eigen::Map<const Vec3>(v_k_ptr)), delta, m.motion, g);
    const PropagatedPose<T> plane = PropagateKeyframe<T>(
        Quat(Eigen::Map<const Quat>(q_j_ptr)), Vec3(Eigen::Map<const Vec3>(p_j_ptr)),
        Vec3(Eigen::Map<const Vec3>(v_j_ptr)), delta, m.plane_motion, g);
    const Vec3 p_W = point.R_W_I * (q_I_L * m.p_L.cast<T>() + p_I_L) + point.p_W_I;
    // T_W_Lj^-1 with the first-order rotation of Eq. (P1) inverted by its transpose.
    const Eigen::Matrix<T, 3, 3> R_W_Lj = plane.R_W_I * q_I_L.toRotationMatrix();
    const Vec3 c_W = plane.R_W_I * p_I_L + plane.p_W_I;
    const Vec3 p_Lj = R_W_Lj.transpose() * (p_W - c_W);
    residual[0] = (m.plane_L.normal.cast<T>().dot(p_Lj) + T(m.plane_L.d)) / T(m.sigma_m);
    return true;
  }

  PointToSweepPlaneMeasurement m;
  Eigen::Vector3d g;
};

ceres::CostFunction* CreatePointToSweepPlaneAutoDiff(
    const PointToSweepPlaneMeasurement& measurement, const Eigen::Vector3d& g_W);

}  // namespace factors
}  // namespace autocal
