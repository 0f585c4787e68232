#include "autocal/sensors/imu_preintegration.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <string>

#include "autocal/common/error.h"
#include "autocal/common/time.h"

namespace autocal {
namespace sensors {

namespace {

using geometry::Hat;

bool IsFinite(const ImuSample& s) { return s.gyro_rad_s.allFinite() && s.accel_m_s2.allFinite(); }

// Linear interpolation between two samples (Eq. F2); a.t_ns < b.t_ns.
ImuSample Lerp(const ImuSample& a, const ImuSample& b, int64_t t_ns) {
  const double w = static_cast<double>(t_ns - a.t_ns) / static_cast<double>(b.t_ns - a.t_ns);
  ImuSample out;
  out.t_ns = t_ns;
  out.gyro_rad_s = (1.0 - w) * a.gyro_rad_s + w * b.gyro_rad_s;
  out.accel_m_s2 = (1.0 - w) * a.accel_m_s2 + w * b.accel_m_s2;
  return out;
}

std::string SampleError(size_t index, const std::string& what) {
  return "IMU sample " + std::to_string(index) + ": " + what;
}

void CheckSample(const ImuSamples& samples, size_t k) {
  if (!IsFinite(samples[k])) throw Error(SampleError(k, "rate or specific force is not finite"));
  if (k > 0 && samples[k].t_ns <= samples[k - 1].t_ns) {
    throw Error(SampleError(k, "timestamp " + std::to_string(samples[k].t_ns) +
                                   " ns does not increase (previous " +
                                   std::to_string(samples[k - 1].t_ns) + " ns)"));
  }
}

// Index of the last sample with t_ns <= t, or throws when t precedes all samples.
size_t LastAtOrBefore(const ImuSamples& samples, int64_t t_ns) {
  const auto it = std::upper_bound(samples.begin(), samples.end(), t_ns,
                                   [](int64_t t, const ImuSample& s) { return t < s.t_ns; });
  if (it == samples.begin()) {
    throw Error("IMU samples do not cover t = " + std::to_string(t_ns) + " ns (" +
                (samples.empty()
                     ? std::string("no samples")
                     : "first sample at " + std::to_string(samples.front().t_ns) + " ns") +
                ")");
  }
  return static_cast<size_t>(it - samples.begin()) - 1;
}

// Per-step rotation angles of an IMU are small (|phi| = |w| dt, well below 0.1 rad), where
// truncated series are exact to rounding (next terms < 3e-15 relative for theta^2 <= 1e-2)
// and avoid the sin/cos of the general forms in so3.h, which dominate a step's cost.
constexpr double kStepSeriesThetaSquared = 1e-2;

Eigen::Quaterniond StepExp(const Eigen::Vector3d& phi) {
  const double t2 = phi.squaredNorm();
  if (t2 > kStepSeriesThetaSquared) return geometry::Exp(phi);
  const double x2 = 0.25 * t2;  // (theta / 2)^2
  const double w = 1.0 - x2 * (0.5 - x2 * (1.0 / 24.0 - x2 * (1.0 / 720.0 - x2 / 40320.0)));
  // sin(theta / 2) / theta
  const double k = 0.5 * (1.0 - x2 * (1.0 / 6.0 - x2 * (1.0 / 120.0 - x2 / 5040.0)));
  return Eigen::Quaterniond(w, k * phi.x(), k * phi.y(), k * phi.z());
}

// Jl(phi) = I + a Hat(phi) + b Hat(phi)^2 with Hat(phi)^2 = phi phi^T - theta^2 I.
Eigen::Matrix3d StepLeftJacobian(const Eigen::Vector3d& phi) {
  const double t2 = phi.squaredNorm();
  if (t2 > kStepSeriesThetaSquared) return geometry::LeftJacobian(phi);
  const double a = 0.5 - t2 * (1.0 / 24.0 - t2 * (1.0 / 720.0 - t2 / 40320.0));
  const double b = 1.0 / 6.0 - t2 * (1.0 / 120.0 - t2 * (1.0 / 5040.0 - t2 / 362880.0));
  Eigen::Matrix3d J = (b * phi) * phi.transpose() + a * Hat(phi);
  J.diagonal().array() += 1.0 - b * t2;
  return J;
}

}  // namespace

ImuSample InterpolateImu(const ImuSamples& samples, int64_t t_ns) {
  const size_t k = LastAtOrBefore(samples, t_ns);
  CheckSample(samples, k);
  if (samples[k].t_ns == t_ns) return samples[k];
  if (k + 1 >= samples.size()) {
    throw Error("IMU samples do not cover t = " + std::to_string(t_ns) + " ns (last sample at " +
                std::to_string(samples.back().t_ns) + " ns)");
  }
  CheckSample(samples, k + 1);
  return Lerp(samples[k], samples[k + 1], t_ns);
}

ImuPreintegration::ImuPreintegration(const ImuNoise& noise, const PreintegrationOptions& options,
                                     const Eigen::Vector3d& b_g_lin, const Eigen::Vector3d& b_a_lin)
    : noise_(noise), options_(options), b_g_lin_(b_g_lin), b_a_lin_(b_a_lin) {
  const double densities[] = {noise.gyroscope_noise_density, noise.gyroscope_random_walk,
                              noise.accelerometer_noise_density, noise.accelerometer_random_walk};
  for (double d : densities) {
    if (!std::isfinite(d) || d < 0.0) {
      throw Error("IMU noise densities must be finite and non-negative, got " + std::to_string(d));
    }
  }
  if (!(options.gravity_m_s2 > 0.0) || !std::isfinite(options.gravity_m_s2)) {
    throw Error("gravity magnitude must be positive, got " + std::to_string(options.gravity_m_s2));
  }
  if (!b_g_lin.allFinite() || !b_a_lin.allFinite()) throw Error("IMU bias is not finite");
  ResetDeltas();
}

void ImuPreintegration::ResetDeltas() {
  dt_s_ = 0.0;
  delta_q_.setIdentity();
  delta_v_.setZero();
  delta_p_.setZero();
  cov_left_.setZero();
  d_theta_d_bg_.setZero();
  d_v_d_bg_.setZero();
  d_v_d_ba_.setZero();
  d_p_d_bg_.setZero();
  d_p_d_ba_.setZero();
}

void ImuPreintegration::Integrate(const ImuSamples& samples, int64_t t_start_ns, int64_t t_end_ns) {
  if (t_end_ns < t_start_ns) {
    throw Error("IMU integration interval ends (" + std::to_string(t_end_ns) +
                " ns) before it starts (" + std::to_string(t_start_ns) + " ns)");
  }
  if (t_end_ns == t_start_ns) return;
  size_t k = LastAtOrBefore(samples, t_start_ns);
  CheckSample(samples, k);
  ImuSample previous = samples[k];
  // Walk the knots t_start < samples in between < t_end; each step uses the mean of the
  // piecewise-linear signal over it, which is the average of its two end values.
  for (++k;; ++k) {
    if (k >= samples.size()) {
      throw Error("IMU samples do not cover t = " + std::to_string(t_end_ns) +
                  " ns (last sample at " + std::to_string(samples.back().t_ns) + " ns)");
    }
    CheckSample(samples, k);
    const ImuSample& next = samples[k];
    const ImuSample start =
        previous.t_ns < t_start_ns ? Lerp(previous, next, t_start_ns) : previous;
    const ImuSample end = next.t_ns > t_end_ns ? Lerp(previous, next, t_end_ns) : next;
    if (end.t_ns > start.t_ns) {
      IntegrateStep(0.5 * (start.gyro_rad_s + end.gyro_rad_s),
                    0.5 * (start.accel_m_s2 + end.accel_m_s2),
                    SecondsBetween(start.t_ns, end.t_ns));
    }
    if (next.t_ns >= t_end_ns) break;
    previous = next;
  }
}

void ImuPreintegration::IntegrateStep(const Eigen::Vector3d& gyro_rad_s,
                                      const Eigen::Vector3d& accel_m_s2, double dt_s) {
  if (!(dt_s > 0.0) || !std::isfinite(dt_s)) {
    throw Error("IMU step length must be positive, got " + std::to_string(dt_s) + " s");
  }
  const Step step{gyro_rad_s, accel_m_s2, dt_s};
  steps_.push_back(step);
  Propagate(step);
}

// Midpoint scheme, Eq. F3: the rotation over the step uses the mean rate (exact for a
// rate of fixed direction), the velocity increment is rotated by the mid-step rotation.
// Both make the deltas second-order accurate in the step length.
void ImuPreintegration::Propagate(const Step& step) {
  const double dt = step.dt_s;
  const Eigen::Vector3d omega = step.gyro_rad_s - b_g_lin_;
  const Eigen::Vector3d accel = step.accel_m_s2 - b_a_lin_;
  const Eigen::Vector3d half_angle = (0.5 * dt) * omega;
  const Eigen::Quaterniond q_half = StepExp(half_angle);
  const Eigen::Quaterniond q_mid = delta_q_ * q_half;
  const Eigen::Matrix3d R_mid = q_mid.toRotationMatrix();
  const Eigen::Vector3d u = R_mid * (accel * dt);  // velocity increment in frame i

  if (options_.compute_covariance) {
    const Eigen::Matrix3d R_k = delta_q_.toRotationMatrix();
    const Eigen::Vector3d full_angle = dt * omega;
    // R_k Jl(w dt) = R_{k+1} Jr(w dt): sensitivity of the left rotation error to the rate.
    const Eigen::Matrix3d g_theta = R_k * StepLeftJacobian(full_angle) * dt;
    const Eigen::Matrix3d g_half = R_k * StepLeftJacobian(half_angle) * (0.5 * dt);
    const Eigen::Matrix3d S = Hat(u);
    const Eigen::Matrix3d g_v_gyro = -S * g_half;  // Eq. F4, gyro input to dv
    const Eigen::Matrix3d g_v_accel = R_mid * dt;
    const double half_dt = 0.5 * dt;

    // Bias Jacobians, Eq. F6 (old values on the right-hand side).
    const Eigen::Matrix3d u_bg = -S * (d_theta_d_bg_ - g_half);
    d_p_d_bg_ += dt * d_v_d_bg_ + half_dt * u_bg;
    d_p_d_ba_ += dt * d_v_d_ba_ - half_dt * g_v_accel;
    d_v_d_bg_ += u_bg;
    d_v_d_ba_ -= g_v_accel;
    d_theta_d_bg_ -= g_theta;

    // Covariance, Eq. F4: P <- A P A^T with
    //   A = I + [0 0 0 | g_theta 0; -S 0 0 | g_v_gyro g_v_accel; -dt/2 S, dt I, 0 | ..; 0 | 0],
    // the p row of the input blocks being dt/2 times the v row. The bias drift enters like a
    // measurement error, so its input blocks equal the noise ones. Applied to rows, then to
    // columns, without forming A.
    auto& P = cov_left_;
    const Eigen::Matrix<double, 3, 15> m_v =
        -S * P.topRows<3>() + g_v_gyro * P.middleRows<3>(9) + g_v_accel * P.middleRows<3>(12);
    P.middleRows<3>(6) += dt * P.middleRows<3>(3) + half_dt * m_v;
    P.middleRows<3>(3) += m_v;
    P.topRows<3>() += g_theta * P.middleRows<3>(9);
    // Columns: only the delta rows; the bias rows of the result are the transpose of the
    // bias columns, which the column pass leaves unchanged (P stays symmetric).
    auto P9 = P.topRows<9>();
    const Eigen::Matrix<double, 9, 3> c_v = P9.leftCols<3>() * S +
                                            P9.middleCols<3>(9) * g_v_gyro.transpose() +
                                            P9.middleCols<3>(12) * g_v_accel.transpose();
    P9.middleCols<3>(6) += dt * P9.middleCols<3>(3) + half_dt * c_v;
    P9.middleCols<3>(3) += c_v;
    P9.leftCols<3>() += P9.middleCols<3>(9) * g_theta.transpose();
    P.bottomLeftCorner<6, 9>() = P.topRightCorner<9, 6>().transpose();

    // + G Qd G^T with Qd = diag(sg^2/dt, sa^2/dt) (Eq. F5); the accelerometer block is
    // rotation invariant: R_mid (sa^2/dt) R_mid^T dt^2 = sa^2 dt I. The bias random walk
    // adds s_w^2 dt per step.
    const double qg = noise_.gyroscope_noise_density * noise_.gyroscope_noise_density / dt;
    const double sa2_dt =
        noise_.accelerometer_noise_density * noise_.accelerometer_noise_density * dt;
    const Eigen::Matrix3d q_tt = qg * g_theta * g_theta.transpose();
    const Eigen::Matrix3d q_tv = qg * g_theta * g_v_gyro.transpose();
    Eigen::Matrix3d q_vv = qg * g_v_gyro * g_v_gyro.transpose();
    q_vv.diagonal().array() += sa2_dt;
    P.block<3, 3>(0, 0) += q_tt;
    P.block<3, 3>(0, 3) += q_tv;
    P.block<3, 3>(3, 0) += q_tv.transpose();
    P.block<3, 3>(0, 6) += half_dt * q_tv;
    P.block<3, 3>(6, 0) += half_dt * q_tv.transpose();
    P.block<3, 3>(3, 3) += q_vv;
    P.block<3, 3>(3, 6) += half_dt * q_vv;
    P.block<3, 3>(6, 3) += half_dt * q_vv;
    P.block<3, 3>(6, 6) += (half_dt * half_dt) * q_vv;
    const double bg = noise_.gyroscope_random_walk;
    const double ba = noise_.accelerometer_random_walk;
    P.block<3, 3>(9, 9).diagonal().array() += bg * bg * dt;
    P.block<3, 3>(12, 12).diagonal().array() += ba * ba * dt;
  }

  delta_p_ += dt * delta_v_ + (0.5 * dt) * u;
  delta_v_ += u;
  delta_q_ = (q_mid * q_half).normalized();
  dt_s_ += dt;
}

void ImuPreintegration::Reintegrate(const Eigen::Vector3d& b_g_lin,
                                    const Eigen::Vector3d& b_a_lin) {
  if (!b_g_lin.allFinite() || !b_a_lin.allFinite()) throw Error("IMU bias is not finite");
  b_g_lin_ = b_g_lin;
  b_a_lin_ = b_a_lin;
  ResetDeltas();
  for (const Step& step : steps_) Propagate(step);
}

bool ImuPreintegration::ReintegrateIfNeeded(const Eigen::Vector3d& b_g,
                                            const Eigen::Vector3d& b_a) {
  const bool gyro_moved =
      (b_g - b_g_lin_).lpNorm<Eigen::Infinity>() > options_.reintegrate_gyro_bias_rad_s;
  const bool accel_moved =
      (b_a - b_a_lin_).lpNorm<Eigen::Infinity>() > options_.reintegrate_accel_bias_m_s2;
  if (!gyro_moved && !accel_moved) return false;
  Reintegrate(b_g, b_a);
  return true;
}

// Right error dphi = dR^T dtheta, so d(dphi)/d(b_g) = dR^T d(dtheta)/d(b_g).
Eigen::Matrix3d ImuPreintegration::d_R_d_bg() const {
  return delta_q_.conjugate().toRotationMatrix() * d_theta_d_bg_;
}

// Left to right rotation error: dphi = dR^T dtheta; the other components are unchanged.
Matrix15d ImuPreintegration::Covariance() const {
  const Eigen::Matrix3d Rt = delta_q_.conjugate().toRotationMatrix();
  Matrix15d cov = cov_left_;
  cov.topRows<3>() = Rt * cov.topRows<3>();
  cov.leftCols<3>() = cov.leftCols<3>() * Rt.transpose();
  return cov;
}

Matrix15d ImuPreintegration::SqrtInformation() const {
  const Matrix15d cov = Covariance();
  const Eigen::LLT<Matrix15d> llt(cov);
  if (llt.info() != Eigen::Success || !(cov.diagonal().array() > 0.0).all()) {
    throw Error("IMU preintegration covariance is not positive definite (interval " +
                std::to_string(dt_s_) + " s, " + std::to_string(steps_.size()) +
                " steps; are the noise densities zero?)");
  }
  // cov = L L^T, so cov^-1 = L^-T L^-1 and U = L^-1 satisfies U^T U = cov^-1.
  Matrix15d sqrt_info = Matrix15d::Identity();
  llt.matrixL().solveInPlace(sqrt_info);
  return sqrt_info;
}

void ImuPreintegration::Corrected(const Eigen::Vector3d& b_g, const Eigen::Vector3d& b_a,
                                  Eigen::Quaterniond* dq, Eigen::Vector3d* dv,
                                  Eigen::Vector3d* dp) const {
  const Eigen::Vector3d dbg = b_g - b_g_lin_;
  const Eigen::Vector3d dba = b_a - b_a_lin_;
  *dq = delta_q_ * geometry::Exp(Eigen::Vector3d(d_R_d_bg() * dbg));
  *dv = delta_v_ + d_v_d_bg_ * dbg + d_v_d_ba_ * dba;
  *dp = delta_p_ + d_p_d_bg_ * dbg + d_p_d_ba_ * dba;
}

}  // namespace sensors
}  // namespace autocal
