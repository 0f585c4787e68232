#pragma once

// On-manifold IMU preintegration (Forster et al. 2017), with no Ceres dependency.
// Derivations and equation numbers: docs/factors.md, section "IMU preintegration".
//
// Between two keyframes i and j the raw samples are summarized by
//   dR = R_i^T R_j,  dv = R_i^T (v_j - v_i - g dt),  dp = R_i^T (p_j - p_i - v_i dt - g dt^2/2)
// evaluated with the linearization biases b_g_lin, b_a_lin (Eq. F1), their first-order
// Jacobians with respect to the biases (Eq. F6) and the 15x15 covariance of the residual
// vector ordered [dphi, dv, dp, db_g, db_a] (Eq. F5), dphi being the right (body-frame)
// perturbation of dR.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "autocal/geometry/so3.h"
#include "autocal/sensors/bias_correction.h"
#include "autocal/sensors/measurements.h"
#include "autocal/sensors/sensor_config.h"

namespace autocal {
namespace sensors {

using Matrix15d = Eigen::Matrix<double, 15, 15>;

struct PreintegrationOptions {
  // Magnitude of gravity; g_W = (0, 0, -gravity_m_s2) in the ENU world frame.
  double gravity_m_s2 = 9.80665;
  // ReintegrateIfNeeded() re-integrates when the bias estimate is farther than this from
  // the linearization point (per-axis max norm). The first-order correction (Eq. F7) has an
  // error quadratic in the change; 1e-3 rad/s keeps it below ~1e-7 rad over 1 s.
  double reintegrate_gyro_bias_rad_s = 1e-3;
  double reintegrate_accel_bias_m_s2 = 1e-2;
  // Covariance and bias Jacobians cost most of a step; propagation of a state to a time
  // inside a sweep does not need them.
  bool compute_covariance = true;
};

// Position, velocity and orientation of the IMU frame in W at one instant.
template <typename T>
struct NavState {
  Eigen::Quaternion<T> q_W_I = Eigen::Quaternion<T>::Identity();
  geometry::Vector3<T> p_W_I = geometry::Vector3<T>::Zero();
  geometry::Vector3<T> v_W_I = geometry::Vector3<T>::Zero();
};
using NavStated = NavState<double>;

class ImuPreintegration {
 public:
  ImuPreintegration(const ImuNoise& noise, const PreintegrationOptions& options,
                    const Eigen::Vector3d& b_g_lin = Eigen::Vector3d::Zero(),
                    const Eigen::Vector3d& b_a_lin = Eigen::Vector3d::Zero());

  // Appends the motion from t_start_ns to t_end_ns. The samples (sorted, finite) are read
  // as a piecewise-linear signal, so a sample interval that straddles t_start_ns or
  // t_end_ns is split and the boundary value interpolated (Eq. F2). Throws autocal::Error
  // when the samples do not cover [t_start_ns, t_end_ns] or are unsorted or not finite.
  void Integrate(const ImuSamples& samples, int64_t t_start_ns, int64_t t_end_ns);

  // One step of length dt_s with the mean measured rate and specific force over the step
  // (raw, bias not removed). Eq. F3 (deltas), F4 (covariance), F6 (bias Jacobians); in a
  // dropout (ImuNoise::max_sample_interval_s) with the unknown signal's variance too (Eq. F5b).
  void IntegrateStep(const Eigen::Vector3d& gyro_rad_s, const Eigen::Vector3d& accel_m_s2,
                     double dt_s, bool in_dropout = false);

  // Re-integrates every stored step with new linearization biases (Sec. "bias
  // correction" of docs/factors.md).
  void Reintegrate(const Eigen::Vector3d& b_g_lin, const Eigen::Vector3d& b_a_lin);
  // Re-integrates when the biases moved beyond the option thresholds; returns whether it did.
  bool ReintegrateIfNeeded(const Eigen::Vector3d& b_g, const Eigen::Vector3d& b_a);

  double dt_s() const { return dt_s_; }
  const Eigen::Quaterniond& delta_q() const { return delta_q_; }
  Eigen::Matrix3d delta_R() const { return delta_q_.toRotationMatrix(); }
  const Eigen::Vector3d& delta_v() const { return delta_v_; }
  const Eigen::Vector3d& delta_p() const { return delta_p_; }
  const Eigen::Vector3d& b_g_lin() const { return b_g_lin_; }
  const Eigen::Vector3d& b_a_lin() const { return b_a_lin_; }
  Eigen::Vector3d gravity_W() const { return Eigen::Vector3d(0.0, 0.0, -options_.gravity_m_s2); }
  const PreintegrationOptions& options() const { return options_; }
  const ImuNoise& noise() const { return noise_; }
  int num_steps() const { return static_cast<int>(steps_.size()); }

  // Bias Jacobians (Eq. F6): dR(b) = dR Exp(d_R_d_bg (b_g - b_g_lin)), and the linear
  // corrections of dv and dp. Valid only with options().compute_covariance.
  Eigen::Matrix3d d_R_d_bg() const;
  const Eigen::Matrix3d& d_v_d_bg() const { return d_v_d_bg_; }
  const Eigen::Matrix3d& d_v_d_ba() const { return d_v_d_ba_; }
  const Eigen::Matrix3d& d_p_d_bg() const { return d_p_d_bg_; }
  const Eigen::Matrix3d& d_p_d_ba() const { return d_p_d_ba_; }

  // Covariance of [dphi, dv, dp, b_g_j - b_g_i, b_a_j - b_a_i] (Eq. F5).
  Matrix15d Covariance() const;
  // Lower-triangular U with U^T U = Covariance()^-1 (the inverse Cholesky factor); throws
  // autocal::Error when the covariance is not positive definite (e.g. an empty interval).
  Matrix15d SqrtInformation() const;

  // The deltas with their bias Jacobians, as the first-order correction (Eq. F7) uses them.
  // Valid only with options().compute_covariance.
  LinearizedDeltas Linearized() const;
  // Deltas corrected to first order for biases (b_g, b_a) (Eq. F7).
  void Corrected(const Eigen::Vector3d& b_g, const Eigen::Vector3d& b_a, Eigen::Quaterniond* dq,
                 Eigen::Vector3d* dv, Eigen::Vector3d* dp) const;
  // The same for any scalar (Jets through Predict and the factors that attach through it);
  // dp may be null when the position is not wanted.
  template <typename T>
  void CorrectedDeltas(const geometry::Vector3<T>& b_g, const geometry::Vector3<T>& b_a,
                       Eigen::Quaternion<T>* dq, geometry::Vector3<T>* dv,
                       geometry::Vector3<T>* dp) const;

  // The state at t_i + dt_s() from the state at t_i (Eq. F8). Templated so that residuals
  // of later factors (LiDAR points inside a sweep, GNSS, wheel between keyframes) can
  // attach to keyframe i through it and differentiate with Jets. The biases are the
  // keyframe's estimates; the correction is first order around the linearization biases.
  template <typename T>
  NavState<T> Predict(const NavState<T>& state_i, const geometry::Vector3<T>& b_g,
                      const geometry::Vector3<T>& b_a) const;

 private:
  struct Step {
    Eigen::Vector3d gyro_rad_s;
    Eigen::Vector3d accel_m_s2;
    double dt_s;
    bool in_dropout;
  };
  // A 3x3 block kept in the top rows of a 4x3 matrix whose last row is zero: each column
  // is two aligned SSE2 packets, so the column combinations that make up the 3x3 products
  // of a step vectorize without any -march flag.
  using Block = Eigen::Matrix<double, 4, 3>;
  // The covariance blocks that change during integration (see the comment on the members).
  // Of the symmetric 9x9 delta block only the lower blocks are kept; the delta-bias block
  // is 9x6 with a zero dtheta-b_a block.
  struct CovarianceBlocks {
    Block tt, vt, vv, pt, pv, pp;  // delta-delta: dtheta, dv, dp
    Block tg, vg, va, pg, pa;      // delta-bias: (dtheta, dv, dp) x (b_g, b_a)
  };

  void ResetDeltas();
  void Propagate(const Step& step);
  // u: the step's velocity increment in frame i (S = Hat(u) in Eq. F4).
  void PropagateCovariance(const Eigen::Vector3d& u, const Block& g_theta, const Block& g_v_gyro,
                           const Block& g_v_accel, double dt_s, bool in_dropout);

  ImuNoise noise_;
  PreintegrationOptions options_;
  Eigen::Vector3d b_g_lin_;
  Eigen::Vector3d b_a_lin_;
  std::vector<Step> steps_;

  double dt_s_ = 0.0;
  Eigen::Quaterniond delta_q_;
  Eigen::Vector3d delta_v_;
  Eigen::Vector3d delta_p_;
  // Covariance and bias Jacobians are propagated for the left (frame-i) rotation error
  // dtheta = dR dphi, whose transition is sparse (Eq. F4); they are rotated to the right
  // error on output. The covariance is kept in blocks: the bias rows of the transition are
  // identity, so the bias-bias block is the random-walk drift since t_i, diag(var_bg I,
  // var_ba I), and only the 9x9 delta block and the 9x6 delta-bias block need products.
  CovarianceBlocks cov_;
  double var_bg_ = 0.0;
  double var_ba_ = 0.0;
  // The step's transition ends with p += dt/2 v (Eq. F4 split, see PropagateCovariance);
  // the blocks above lack it for the last step, so that the next step applies it together
  // with its own first one, and Covariance() applies it on output.
  double cov_pending_half_dt_s_ = 0.0;
  Block d_theta_d_bg_;
  Eigen::Matrix3d d_v_d_bg_;
  Eigen::Matrix3d d_v_d_ba_;
  Eigen::Matrix3d d_p_d_bg_;
  Eigen::Matrix3d d_p_d_ba_;
};

// The rate and specific force at t_ns, linearly interpolated between the bracketing samples.
// Throws autocal::Error outside the samples' time span.
ImuSample InterpolateImu(const ImuSamples& samples, int64_t t_ns);

// Whether a sample (samples sorted by time) is stamped strictly between after_ns and
// before_ns. Without one the preintegration over (after_ns, before_ns) is a single
// interpolated step, whose position and velocity errors share one noise draw: its covariance
// is singular and no IMU factor can be formed (an IMU dropout, or keyframes closer than the
// IMU's period). Keyframes are placed so that every interval holds one.
bool ImuSampleBetween(const ImuSamples& samples, int64_t after_ns, int64_t before_ns);

// The mean of the gyro samples stamped in [t0_ns, t1_ns] (samples sorted by time), and how many
// there were; zero and 0 when none.
struct GyroMean {
  Eigen::Vector3d rate_rad_s = Eigen::Vector3d::Zero();
  int samples = 0;
};
GyroMean MeanGyro(const ImuSamples& samples, int64_t t0_ns, int64_t t1_ns);
// The mean gyro over half_span_ns on either side of t_ns, or, when that holds no sample, the
// gyro interpolated at t_ns with samples 0 (InterpolateImu, which throws outside the samples).
GyroMean GyroAround(const ImuSamples& samples, int64_t t_ns, int64_t half_span_ns);
// GyroAround at every period_ns (> 0) from the first sample to the last; empty without samples.
std::vector<GyroMean> GyroAroundOverLog(const ImuSamples& samples, int64_t period_ns,
                                        int64_t half_span_ns);

template <typename T>
void ImuPreintegration::CorrectedDeltas(const geometry::Vector3<T>& b_g,
                                        const geometry::Vector3<T>& b_a, Eigen::Quaternion<T>* dq,
                                        geometry::Vector3<T>* dv, geometry::Vector3<T>* dp) const {
  Linearized().Corrected(b_g, b_a, dq, dv, dp);
}

template <typename T>
NavState<T> ImuPreintegration::Predict(const NavState<T>& state_i, const geometry::Vector3<T>& b_g,
                                       const geometry::Vector3<T>& b_a) const {
  Eigen::Quaternion<T> dq;
  geometry::Vector3<T> dv, dp;
  CorrectedDeltas(b_g, b_a, &dq, &dv, &dp);
  const T dt(dt_s_);
  const geometry::Vector3<T> g = gravity_W().cast<T>();
  NavState<T> out;
  out.q_W_I = state_i.q_W_I * dq;
  out.v_W_I = state_i.v_W_I + g * dt + state_i.q_W_I * dv;
  out.p_W_I = state_i.p_W_I + state_i.v_W_I * dt + T(0.5) * g * dt * dt + state_i.q_W_I * dp;
  return out;
}

}  // namespace sensors
}  // namespace autocal
