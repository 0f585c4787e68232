#pragma once

// Private building blocks of the sliding window (docs/sliding_window.md, "Factors"): wheel and
// GNSS residuals at an instant between keyframes, attached to the earlier keyframe through
// IMU propagation (sensors::ImuPreintegration::Predict, Eq. F8), and the compressed form of a
// point group the solver sees (Eq. W3).

#include <ceres/ceres.h>

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/estimation/gnss_noise.h"
#include "autocal/factors/gnss_factor.h"
#include "autocal/factors/point_to_sweep_plane_group_factor.h"
#include "autocal/factors/wheel_factor.h"
#include "autocal/geometry/manifolds.h"
#include "autocal/geometry/so3.h"
#include "autocal/sensors/imu_preintegration.h"
#include "estimation/lower_gram.h"

namespace autocal {
namespace estimation {
namespace internal {

// A residual block kept between updates: its cost function, its loss (owned by the
// estimator, nullptr = plain least squares) and its parameter blocks.
struct AttachedFactor {
  std::unique_ptr<ceres::CostFunction> cost;
  ceres::LossFunction* loss = nullptr;
  std::vector<double*> blocks;
  // Given to the solver linearized at the start of each pass (LinearizedCost, "Linearized once per
  // pass"), with its loss's weight held for the pass (Eq. W4), when the points are; what it names
  // on an evaluation failure.
  const char* linearized_per_pass = nullptr;
  // A GNSS factor's (east, north, up rows): the scale its fix's std was attached with (Eq. N2).
  std::optional<GnssStdScale> gnss_std_scale;
};

// The state at the sample's instant, x(t) = Predict(x_k, b_g_k, b_a_k) (Eq. F8) with the
// preintegration from the keyframe to t; the bias at t is the keyframe's (random walk over
// one interval neglected, as the IMU factor's bias rows assume).
template <typename T>
sensors::NavState<T> PropagatedState(const sensors::ImuPreintegration& pim, const T* q_ptr,
                                     const T* p_ptr, const T* v_ptr, const T* b_g_ptr,
                                     const T* b_a_ptr) {
  sensors::NavState<T> state;
  state.q_W_I = Eigen::Map<const Eigen::Quaternion<T>>(q_ptr);
  state.p_W_I = Eigen::Map<const geometry::Vector3<T>>(p_ptr);
  state.v_W_I = Eigen::Map<const geometry::Vector3<T>>(v_ptr);
  return pim.Predict(state, geometry::Vector3<T>(Eigen::Map<const geometry::Vector3<T>>(b_g_ptr)),
                     geometry::Vector3<T>(Eigen::Map<const geometry::Vector3<T>>(b_a_ptr)));
}

// The propagated state of ImuPreintegration::Predict (Eq. F7-F8), only as far as the wheel
// rows see it: they read the velocity in the body frame, R_t^T v_t with R_t = R_k dR and
// v_t = v_k + g dt + R_k dv, which is dR^T (R_k^T (v_k + g dt) + dv). So a wheel residual is
// given dR for the attitude and R_k^T (v_k + g dt) + dv for the velocity: no product R_k dR,
// and no position.
template <typename T>
void PropagatedBodyInputs(const sensors::ImuPreintegration& pim, const T* q, const T* v,
                          const T* b_g, const T* b_a, Eigen::Quaternion<T>* dq,
                          geometry::Vector3<T>* v_in_k) {
  using Vec3 = geometry::Vector3<T>;
  Vec3 dv;
  pim.CorrectedDeltas<T>(Eigen::Map<const Vec3>(b_g), Eigen::Map<const Vec3>(b_a), dq, &dv,
                         nullptr);
  const Vec3 g_dt = (pim.gravity_W() * pim.dt_s()).cast<T>();
  const Eigen::Map<const Eigen::Quaternion<T>> q_k(q);
  *v_in_k = q_k.conjugate() * Vec3(Eigen::Map<const Vec3>(v) + g_dt) + dv;
}

// Eq. W7 (docs/sliding_window.md, "Wheel rows"): the covariance, in V, of the body velocity
// the wheel rows read at the state propagated by `pim` from a keyframe at (q_W_I, v_W_I). That
// state is not a block of the window, and it carries the preintegration's noise: with the
// right attitude error dphi and the velocity error d(dv) of ImuPreintegration::Covariance(),
// u = dR^T (R_k^T (v_k + g dt) + dv) = Exp(-dphi) dR^T (...) moves by
//   du = Hat(u) dphi + dR^T d(dv),   Cov(u) = A Cov[dphi, dv] A^T,   A = [Hat(u)  dR^T],
// and the rows, along x, y and z of V, see R_V_I Cov(u) R_V_I^T. The rows of one interval share
// this noise, and with the IMU factor over it; those correlations are not modelled.
inline Eigen::Matrix3d PropagatedVelocityCovariance(const sensors::ImuPreintegration& pim,
                                                    const Eigen::Quaterniond& q_W_I,
                                                    const Eigen::Vector3d& v_W_I,
                                                    const Eigen::Quaterniond& q_I_V) {
  const Eigen::Matrix3d dR_T = pim.delta_R().transpose();
  const Eigen::Vector3d u =
      dR_T * (q_W_I.conjugate() * (v_W_I + pim.gravity_W() * pim.dt_s()) + pim.delta_v());
  Eigen::Matrix<double, 3, 6> A;
  A << geometry::Hat(u), dR_T;
  const Eigen::Matrix3d R_V_I = q_I_V.conjugate().toRotationMatrix();
  return R_V_I * A * pim.Covariance().topLeftCorner<6, 6>() * A.transpose() * R_V_I.transpose();
}

// Wheel residual (Eq. F22) at the propagated state, with the speed and yaw-rate rows whitened at
// the current radii and track width (docs/sliding_window.md, "Wheel rows"), s_w the encoder and
// s_g the gyro sample noise: row 0 over s_v = sqrt(s_w^2 (r_l^2 + r_r^2) / 4 + V), V the variance
// added to the speed row (the propagated velocity's along x_V, Eq. W7, and the body rate's
// remaining error through the lever arm, Eq. K13), row 1 in wheel-speed units, (w_z b - (w_r r_r -
// w_l r_l)), over sqrt(s_w^2 (r_l^2 + r_r^2) + b^2 s_g^2): the Deming weighting of Eq. F22b in its
// general form, evaluated here at the current radii (the keyframe factor's YawRowSigma is its
// fixed-radii case). Parameter blocks: q_W_I, v_W_I, b_g, b_a of the keyframe (its position does
// not enter the wheel rows), then q_I_V, p_I_V, r_l, r_r, track width.
class PropagatedWheelResidual {
 public:
  PropagatedWheelResidual(sensors::ImuPreintegration pim,
                          const factors::WheelMeasurement& measurement,
                          const factors::WheelFactorOptions& options, double encoder_sigma_rad_s,
                          double gyro_sigma_rad_s, double speed_variance_m2_s2)
      : pim_(std::move(pim)),
        wheel_(measurement, options),
        speed_sigma_m_s_(options.speed_sigma_m_s),
        yaw_rate_sigma_rad_s_(options.yaw_rate_sigma_rad_s),
        encoder_sigma_rad_s_(encoder_sigma_rad_s),
        gyro_sigma_rad_s_(gyro_sigma_rad_s),
        speed_variance_m2_s2_(speed_variance_m2_s2) {}

  // encoder_sigma_rad_s: 1-sigma of each wheel rate; gyro_sigma_rad_s: 1-sigma of one gyro
  // sample (noise density times the square root of the IMU rate); speed_variance_m2_s2: V.
  static ceres::CostFunction* Create(sensors::ImuPreintegration pim,
                                     const factors::WheelMeasurement& measurement,
                                     const factors::WheelFactorOptions& options,
                                     double encoder_sigma_rad_s, double gyro_sigma_rad_s,
                                     double speed_variance_m2_s2) {
    return new ceres::AutoDiffCostFunction<PropagatedWheelResidual, ceres::DYNAMIC, 4, 3, 3, 3, 4,
                                           3, 1, 1, 1>(
        new PropagatedWheelResidual(std::move(pim), measurement, options, encoder_sigma_rad_s,
                                    gyro_sigma_rad_s, speed_variance_m2_s2),
        options.non_holonomic ? 4 : 2);
  }

  template <typename T>
  bool operator()(const T* q, const T* v, const T* b_g, const T* b_a, const T* q_I_V,
                  const T* p_I_V, const T* r_l, const T* r_r, const T* track_width,
                  T* residual) const {
    Eigen::Quaternion<T> dq;
    geometry::Vector3<T> v_in_k;
    PropagatedBodyInputs(pim_, q, v, b_g, b_a, &dq, &v_in_k);
    if (!wheel_(dq.coeffs().data(), v_in_k.data(), b_g, q_I_V, p_I_V, r_l, r_r, track_width,
                residual)) {
      return false;
    }
    using std::sqrt;
    const T radius_sq = r_l[0] * r_l[0] + r_r[0] * r_r[0];
    const T s_w(encoder_sigma_rad_s_), s_g(gyro_sigma_rad_s_);
    // Speed row: back to metres per second, over s_v at the current radii.
    residual[0] *=
        T(speed_sigma_m_s_) / sqrt(T(0.25) * s_w * s_w * radius_sq + T(speed_variance_m2_s2_));
    // Yaw-rate row: (w_z - y / b) / s_yaw0 times s_yaw0 b is w_z b - y.
    const T b = track_width[0];
    residual[1] *= T(yaw_rate_sigma_rad_s_) * b / sqrt(s_w * s_w * radius_sq + b * b * s_g * s_g);
    return true;
  }

 private:
  sensors::ImuPreintegration pim_;
  factors::WheelResidual wheel_;
  double speed_sigma_m_s_;  // the sigmas wheel_ whitens with
  double yaw_rate_sigma_rad_s_;
  double encoder_sigma_rad_s_;
  double gyro_sigma_rad_s_;
  double speed_variance_m2_s2_;
};

// PropagatedWheelResidual with analytic Jacobians (its autodiff form is the test oracle):
// factors::WheelFactor at the propagated attitude dR = dR_0 Exp(A (b_g - b_g0)) and body
// velocity u = R_k^T (v_k + g dt) + dv, dv = dv_0 + B_g (b_g - b_g0) + B_a (b_a - b_a0)
// (ImuPreintegration::CorrectedDeltas), its rows chained to the keyframe's blocks:
//   d/d(theta_k) = J_u Hat(R_k^T (v_k + g dt)),   d/dv_k = J_u R_k^T,
//   d/db_g = J_bg + J_dR Jr(A (b_g - b_g0)) A + J_u B_g,   d/db_a = J_u B_a,
// then whitened at the current radii and track width as PropagatedWheelResidual (the scales' own
// derivatives in r_l, r_r and b added). The same blocks as PropagatedWheelResidual. Linearizing a
// window's wheel rows through Jets of 23 took about a tenth of its update.
class PropagatedWheelFactor final : public ceres::CostFunction {
 public:
  PropagatedWheelFactor(sensors::ImuPreintegration pim,
                        const factors::WheelMeasurement& measurement,
                        const factors::WheelFactorOptions& options, double encoder_sigma_rad_s,
                        double gyro_sigma_rad_s, double speed_variance_m2_s2);

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

 private:
  sensors::ImuPreintegration pim_;
  factors::WheelFactor wheel_;
  double speed_sigma_m_s_;
  double yaw_rate_sigma_rad_s_;
  double encoder_sigma_rad_s_;
  double gyro_sigma_rad_s_;
  double speed_variance_m2_s2_;
};

// Wheels reported as the rear pair's linear speeds (factors::WheelSpeedResidual, Eq. F25) at
// the propagated state, whitened at the current scales as the wheel rows are ("Wheel rows")
// with the per-wheel speed noise s and the gyro's: the speed row by
// sqrt(s^2 (s_l^2 + s_r^2) / 4 + V) at the current scales (V as for PropagatedWheelResidual), the
// yaw-rate row taken in speed units, w_z b - (s_r v_r - s_l v_l), over sqrt(s^2 (s_l^2 + s_r^2) +
// b^2 s_g^2) (Deming: with the yaw row's sigma fixed, the wheels' own noise attenuated 1 / b and
// the track ended 1.9 % long on the simulated urban drive). Parameter blocks: q_W_I, v_W_I, b_g,
// b_a of the keyframe, then q_I_V, p_I_V, s_l, s_r, b.
class PropagatedWheelSpeedResidual {
 public:
  PropagatedWheelSpeedResidual(sensors::ImuPreintegration pim,
                               const factors::WheelSpeedMeasurement& measurement,
                               const factors::WheelFactorOptions& options, double speed_sigma_m_s,
                               double gyro_sigma_rad_s, double speed_variance_m2_s2)
      : pim_(std::move(pim)),
        wheel_(measurement, options),
        row_sigmas_(options.speed_sigma_m_s, options.yaw_rate_sigma_rad_s),
        speed_sigma_m_s_(speed_sigma_m_s),
        gyro_sigma_rad_s_(gyro_sigma_rad_s),
        speed_variance_m2_s2_(speed_variance_m2_s2) {}

  // speed_sigma_m_s: 1-sigma of each reported wheel speed; gyro_sigma_rad_s: of the gyro's mean;
  // speed_variance_m2_s2: V.
  static ceres::CostFunction* Create(sensors::ImuPreintegration pim,
                                     const factors::WheelSpeedMeasurement& measurement,
                                     const factors::WheelFactorOptions& options,
                                     double speed_sigma_m_s, double gyro_sigma_rad_s,
                                     double speed_variance_m2_s2) {
    return new ceres::AutoDiffCostFunction<PropagatedWheelSpeedResidual, ceres::DYNAMIC, 4, 3, 3, 3,
                                           4, 3, 1, 1, 1>(
        new PropagatedWheelSpeedResidual(std::move(pim), measurement, options, speed_sigma_m_s,
                                         gyro_sigma_rad_s, speed_variance_m2_s2),
        options.non_holonomic ? 4 : 2);
  }

  template <typename T>
  bool operator()(const T* q, const T* v, const T* b_g, const T* b_a, const T* q_I_V,
                  const T* p_I_V, const T* s_l, const T* s_r, const T* track, T* residual) const {
    Eigen::Quaternion<T> dq;
    geometry::Vector3<T> v_in_k;
    PropagatedBodyInputs(pim_, q, v, b_g, b_a, &dq, &v_in_k);
    if (!wheel_(dq.coeffs().data(), v_in_k.data(), b_g, q_I_V, p_I_V, s_l, s_r, track, residual)) {
      return false;
    }
    using std::sqrt;
    const T scale_sq = s_l[0] * s_l[0] + s_r[0] * s_r[0];
    const T s(speed_sigma_m_s_), s_g(gyro_sigma_rad_s_), b = track[0];
    residual[0] *= T(row_sigmas_.x()) / sqrt(T(0.25) * s * s * scale_sq + T(speed_variance_m2_s2_));
    residual[1] *= T(row_sigmas_.y()) * b / sqrt(s * s * scale_sq + b * b * s_g * s_g);
    return true;
  }

 private:
  sensors::ImuPreintegration pim_;
  factors::WheelSpeedResidual wheel_;
  Eigen::Vector2d row_sigmas_;  // the speed and yaw-rate sigmas wheel_ whitens with
  double speed_sigma_m_s_;
  double gyro_sigma_rad_s_;
  double speed_variance_m2_s2_;
};

// Wheels reported as the controller's speed and yaw rate (factors::OdometryTwistResidual,
// Eq. F26) at the propagated state, the yaw-rate row in the same Deming form:
// w_z b_eff - k_v w_odo b_ctrl over sqrt((k_v b_ctrl s_w)^2 + b_eff^2 s_g^2), s_w the yaw
// rate's noise. Parameter blocks: q_W_I, v_W_I, b_g, b_a of the keyframe, then q_I_V, p_I_V,
// k_v, b_eff.
class PropagatedOdometryResidual {
 public:
  PropagatedOdometryResidual(sensors::ImuPreintegration pim,
                             const factors::OdometryMeasurement& measurement,
                             const factors::WheelFactorOptions& options, double gyro_sigma_rad_s)
      : pim_(std::move(pim)),
        odometry_(measurement, options),
        controller_track_m_(measurement.controller_track_m),
        yaw_rate_sigma_rad_s_(options.yaw_rate_sigma_rad_s),
        gyro_sigma_rad_s_(gyro_sigma_rad_s) {}

  static ceres::CostFunction* Create(sensors::ImuPreintegration pim,
                                     const factors::OdometryMeasurement& measurement,
                                     const factors::WheelFactorOptions& options,
                                     double gyro_sigma_rad_s) {
    return new ceres::AutoDiffCostFunction<PropagatedOdometryResidual, ceres::DYNAMIC, 4, 3, 3, 3,
                                           4, 3, 1, 1>(
        new PropagatedOdometryResidual(std::move(pim), measurement, options, gyro_sigma_rad_s),
        options.non_holonomic ? 4 : 2);
  }

  template <typename T>
  bool operator()(const T* q, const T* v, const T* b_g, const T* b_a, const T* q_I_V,
                  const T* p_I_V, const T* speed_scale, const T* effective_track,
                  T* residual) const {
    Eigen::Quaternion<T> dq;
    geometry::Vector3<T> v_in_k;
    PropagatedBodyInputs(pim_, q, v, b_g, b_a, &dq, &v_in_k);
    if (!odometry_(dq.coeffs().data(), v_in_k.data(), b_g, q_I_V, p_I_V, speed_scale,
                   effective_track, residual)) {
      return false;
    }
    using std::sqrt;
    const T wheel_part = speed_scale[0] * T(controller_track_m_ * yaw_rate_sigma_rad_s_);
    const T b = effective_track[0], s_g(gyro_sigma_rad_s_);
    residual[1] *= T(yaw_rate_sigma_rad_s_) * b / sqrt(wheel_part * wheel_part + b * b * s_g * s_g);
    return true;
  }

 private:
  sensors::ImuPreintegration pim_;
  factors::OdometryTwistResidual odometry_;
  double controller_track_m_;
  double yaw_rate_sigma_rad_s_;
  double gyro_sigma_rad_s_;
};

// GNSS residual (Eq. F30) at the propagated state.
// Parameter blocks: q_W_I, p_W_I, v_W_I, b_g, b_a of the keyframe, then p_I_A.
class PropagatedGnssResidual {
 public:
  PropagatedGnssResidual(sensors::ImuPreintegration pim, const factors::GnssMeasurement& m)
      : pim_(std::move(pim)), gnss_(m) {}

  static ceres::CostFunction* Create(sensors::ImuPreintegration pim,
                                     const factors::GnssMeasurement& m) {
    return new ceres::AutoDiffCostFunction<PropagatedGnssResidual, 3, 4, 3, 3, 3, 3, 3>(
        new PropagatedGnssResidual(std::move(pim), m));
  }

  template <typename T>
  bool operator()(const T* q, const T* p, const T* v, const T* b_g, const T* b_a, const T* p_I_A,
                  T* residual) const {
    const sensors::NavState<T> x = PropagatedState(pim_, q, p, v, b_g, b_a);
    return gnss_(x.q_W_I.coeffs().data(), x.p_W_I.data(), p_I_A, residual);
  }

 private:
  sensors::ImuPreintegration pim_;
  factors::GnssResidual gnss_;
};

// A point group (factors::PointToSweepPlaneGroupFactor, n rows) compressed to kRows rows with
// the same cost, gradient and Gauss-Newton matrix (docs/sliding_window.md, Eq. W3). The
// group's Jacobian has 22 independent columns, T: the tangents of its three quaternions, p_k,
// v_k, v_j, p_I_L and the offset (its p_j columns are minus its p_k columns). With its residual
// r and Jacobian J_T (n x 22) in those columns and the pivoted factorization
// J_T^T J_T = P^T L D L^T P, the block returns
//   rows 0-21: rho = D^-1/2 L^-1 P J_T^T r,   Jacobian R_T M, R_T = D^1/2 L^T P,
//   row 22:    sqrt(|r|^2 - |rho|^2),         Jacobian 0,
// M (22 x 28) mapping T to the ambient coordinates of the nine blocks (the quaternions'
// QuaternionMinusJacobian, -I for p_j); pivots D_i below kRelativePivot max D count as zero
// (their rows are 0). So (R_T M)^T R_T M = M^T J_T^T J_T M = J^T J, likewise for the gradient,
// and |rho|^2 + row_22^2 = |r|^2. The solver's cost, gradient, linear model and Jacobian
// scaling are those of the n-row block (the manifolds act on R_T M as on J), but its normal
// equations are formed from 23 rows instead of n. Worth it for n > kRows.
class CompressedPointGroup final : public ceres::CostFunction {
 public:
  static constexpr int kAmbient = 28;  // 4 + 3 + 3 + 4 + 3 + 3 + 4 + 3 + 1
  static constexpr int kIndependent = 22;
  static constexpr int kRows = kIndependent + 1;
  static constexpr double kRelativePivot = 1e-12;

  // `group` must outlive this cost function.
  explicit CompressedPointGroup(const factors::PointToSweepPlaneGroupFactor* group)
      : group_(group) {
    set_num_residuals(kRows);
    *mutable_parameter_block_sizes() = group->parameter_block_sizes();
  }

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    using Square = Eigen::Matrix<double, kIndependent, kIndependent>;
    using Vector = Eigen::Matrix<double, kIndependent, 1>;
    using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
    const int n = group_->num_residuals();
    static_assert(kAmbient == factors::PointToSweepPlaneGroupFactor::kAmbientSize,
                  "the group's blocks are the compressed block's");
    Eigen::VectorXd r(n);
    Eigen::Map<Vector> rho(residuals);
    if (jacobians == nullptr) {
      // Only the cost is asked for: any rows with the same norm will do.
      if (!group_->Evaluate(parameters, r.data(), nullptr)) return false;
      rho.setZero();
      residuals[kIndependent] = r.norm();
      return true;
    }
    // The group writes J_T column-major (PointToSweepPlaneGroupFactor::EvaluateTangent), the
    // layout J_T^T J_T and J_T^T r are formed fastest from (docs/sliding_window.md, "Memory
    // kept, copies avoided").
    static_assert(kIndependent == factors::PointToSweepPlaneGroupFactor::kTangentColumns,
                  "the group's tangent columns are the compressed block's");
    Eigen::Matrix<double, Eigen::Dynamic, kIndependent> J(n, kIndependent);
    if (!group_->EvaluateTangent(parameters, r.data(), J.data())) return false;
    Square A;
    Vector g;
    LowerGramAndGradient(J.data(), n, kIndependent, r.data(), A.data(), g.data());
    A.triangularView<Eigen::StrictlyUpper>() = A.transpose();

    const Eigen::LDLT<Square> ldlt(A);
    const Vector d = ldlt.vectorD();
    const double threshold = kRelativePivot * std::max(d.maxCoeff(), 0.0);
    Vector y = ldlt.transpositionsP() * g;
    ldlt.matrixL().solveInPlace(y);
    // R_T = U (P I): U with its columns moved, no matrix product (Eigen's product with the
    // transpositions' transpose moves the columns as the permutation matrix P I does).
    Square R = Square(ldlt.matrixU()) * ldlt.transpositionsP().transpose();
    for (int i = 0; i < kIndependent; ++i) {
      if (d(i) > threshold) {
        const double root = std::sqrt(d(i));
        rho(i) = y(i) / root;
        R.row(i) *= root;
      } else {
        rho(i) = 0.0;
        R.row(i).setZero();
      }
    }
    residuals[kIndependent] = std::sqrt(std::max(0.0, r.squaredNorm() - rho.squaredNorm()));
    // R_T M, block by block.
    const std::vector<int32_t>& sizes = parameter_block_sizes();
    for (size_t b = 0; b < sizes.size(); ++b) {
      if (jacobians[b] == nullptr) continue;
      Eigen::Map<RowMajor> out(jacobians[b], kRows, sizes[b]);
      const auto columns = R.middleCols(kIndependentColumn[b], sizes[b] == 4 ? 3 : sizes[b]);
      if (sizes[b] == 4) {
        out.topRows(kIndependent) = columns * geometry::QuaternionMinusJacobian(parameters[b]);
      } else if (b == kPositionJ) {
        out.topRows(kIndependent) = -columns;
      } else {
        out.topRows(kIndependent) = columns;
      }
      out.row(kIndependent).setZero();
    }
    return true;
  }

 private:
  // The first column of block b in J_T (p_j: p_k's).
  static constexpr int kIndependentColumn[9] = {0, 3, 6, 9, 3, 12, 15, 18, 21};
  static constexpr size_t kPositionJ = 4;

  const factors::PointToSweepPlaneGroupFactor* group_;
};

// A cost function linearized once per solve pass (docs/sliding_window.md, "Linearized once per
// pass"): its rows r and Jacobian J (ambient coordinates of its blocks) are evaluated at the
// parameters x0 it is built at, and the solver sees the first-order model
//   r(x) = r(x0) + J (x - x0),
// so that a Levenberg-Marquardt iteration costs one product instead of an evaluation of the
// cost function. Given a robust loss rho, the rows are weighted as at x0 (Eq. W4):
//   r(x) = sqrt(rho'(|r0|^2)) (r0 + J (x - x0)),
// the loss's weight held for the pass as the point groups' is (Ceres' correction of a row
// block for a loss with rho'' <= 0, as Huber and Cauchy, is this weight). The parameters must
// stay at x0's side of the quaternion sign. kRows and kAmbient are the sizes when known at
// compile time.
template <int kRows = Eigen::Dynamic, int kAmbient = Eigen::Dynamic>
class LinearizedCost final : public ceres::CostFunction {
 public:
  // Throws autocal::Error naming `what` when `cost` cannot be evaluated at `parameters`.
  LinearizedCost(const ceres::CostFunction& cost, const std::vector<double*>& parameters,
                 const char* what, const ceres::LossFunction* loss = nullptr) {
    set_num_residuals(cost.num_residuals());
    *mutable_parameter_block_sizes() = cost.parameter_block_sizes();
    const std::vector<int32_t>& sizes = parameter_block_sizes();
    const int rows = cost.num_residuals();
    int ambient = 0;
    for (int32_t size : sizes) ambient += size;
    r0_.resize(rows);
    J_.resize(rows, ambient);
    x0_.resize(ambient);
    std::vector<Eigen::Matrix<double, kRows, Eigen::Dynamic, Eigen::RowMajor>> blocks(sizes.size());
    std::vector<double*> jacobians(sizes.size());
    for (size_t b = 0; b < sizes.size(); ++b) {
      blocks[b].resize(rows, sizes[b]);
      jacobians[b] = blocks[b].data();
    }
    std::vector<const double*> values(parameters.begin(), parameters.end());
    if (!cost.Evaluate(values.data(), r0_.data(), jacobians.data())) {
      throw Error(std::string("SlidingWindowEstimator: ") + what + " cannot be evaluated");
    }
    for (size_t b = 0, column = 0; b < sizes.size(); column += static_cast<size_t>(sizes[b++])) {
      const Eigen::Index c = static_cast<Eigen::Index>(column);
      J_.middleCols(c, sizes[b]) = blocks[b];
      x0_.segment(c, sizes[b]) = Eigen::Map<const Eigen::VectorXd>(parameters[b], sizes[b]);
    }
    if (loss != nullptr) {
      double rho[3];
      loss->Evaluate(r0_.squaredNorm(), rho);
      const double weight = std::sqrt(std::max(rho[1], 0.0));
      r0_ *= weight;
      J_ *= weight;
    }
  }

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const std::vector<int32_t>& sizes = parameter_block_sizes();
    Eigen::Matrix<double, kAmbient, 1> dx(x0_.size());
    for (size_t b = 0, column = 0; b < sizes.size(); column += static_cast<size_t>(sizes[b++])) {
      const Eigen::Index c = static_cast<Eigen::Index>(column);
      dx.segment(c, sizes[b]) =
          Eigen::Map<const Eigen::VectorXd>(parameters[b], sizes[b]) - x0_.segment(c, sizes[b]);
    }
    Eigen::Map<Eigen::Matrix<double, kRows, 1>> r(residuals, r0_.size());
    r = r0_ + J_ * dx;
    if (jacobians == nullptr) return true;
    for (size_t b = 0, column = 0; b < sizes.size(); column += static_cast<size_t>(sizes[b++])) {
      if (jacobians[b] == nullptr) continue;
      Eigen::Map<Eigen::Matrix<double, kRows, Eigen::Dynamic, Eigen::RowMajor>> out(
          jacobians[b], r0_.size(), sizes[b]);
      out = J_.middleCols(static_cast<Eigen::Index>(column), sizes[b]);
    }
    return true;
  }

 private:
  Eigen::Matrix<double, kRows, 1> r0_;
  Eigen::Matrix<double, kRows, kAmbient> J_;
  Eigen::Matrix<double, kAmbient, 1> x0_;
};

// A point group linearized per pass: its compressed rows (Eq. W3, a 29 x 28 product per group
// instead of the group's n point Jacobians and their compression at every iteration; row 28
// stays constant).
using LinearizedPointGroup =
    LinearizedCost<CompressedPointGroup::kRows, CompressedPointGroup::kAmbient>;

inline std::unique_ptr<ceres::CostFunction> LinearizePointGroup(
    const factors::PointToSweepPlaneGroupFactor* group, const std::vector<double*>& parameters) {
  return std::make_unique<LinearizedPointGroup>(CompressedPointGroup(group), parameters,
                                                "a point group");
}

}  // namespace internal
}  // namespace estimation
}  // namespace autocal
