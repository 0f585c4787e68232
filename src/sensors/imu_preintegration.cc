#include "autocal/sensors/imu_preintegration.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <string>

#include "autocal/common/error.h"
#include "autocal/common/time.h"
#include "sensors/padded_block.h"

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

using Block = internal::PaddedBlock;
using internal::MinusHatTimes;
using internal::Padded;
using internal::SetColumn;
using internal::TimesHat;
using internal::TimesTransposed;
using internal::Transposed;

// P <- E P E^T for E: p += h v on the blocks D (9x9, symmetric) and B (9x6) of the
// covariance, by columns (contiguous): the p columns, then the p-p block takes the row
// update, and the p rows are mirrored.
void AddVelocityToPosition(double h, Eigen::Matrix<double, 9, 9>* D,
                           Eigen::Matrix<double, 9, 6>* B) {
  D->middleCols<3>(6) += h * D->middleCols<3>(3);
  D->block<3, 3>(6, 6) += h * D->block<3, 3>(3, 6);
  D->block<3, 6>(6, 0) = D->block<6, 3>(0, 6).transpose();
  B->middleRows<3>(6) += h * B->middleRows<3>(3);
}

// The two rate sensitivities of a step, g_full = dt R_k Jl(phi) for the full step angle
// phi = w dt and g_half = dt/2 R_k Jl(phi / 2), from the mid-step rotation R_mid = R_k H,
// H = Exp(phi / 2), which the deltas need anyway. Since Jl(x) = Exp(x) Jr(x):
//   g_half = dt/2 R_mid H^T Jl(phi/2) = dt/2 R_mid Jr(phi/2),
//   g_full = dt R_mid H^T Exp(phi) Jr(phi) = dt R_mid Exp(phi/2) Jr(phi) = dt R_mid Jm(phi),
// Jm(phi) = int_{-1/2}^{1/2} Exp(s phi) ds = I + c Hat(phi)^2, c = (1 - sin(t/2) 2/t) / t^2
// (the odd part of the integrand cancels). With Hat(phi)^2 = phi phi^T - t^2 I both are
// combinations of R_mid, R_mid Hat(phi) and (R_mid phi) phi^T.
void StepRateJacobians(const Block& R_mid, const Eigen::Vector3d& phi, double dt, Block* g_full,
                       Block* g_half) {
  const double t2 = phi.squaredNorm();
  const double half_dt = 0.5 * dt;
  if (t2 > kStepSeriesThetaSquared) {
    const Eigen::Matrix3d R = R_mid.topRows<3>();
    const Eigen::Vector3d half_phi = 0.5 * phi;
    *g_full = Padded(R * (geometry::ExpMatrix(half_phi) * geometry::RightJacobian(phi)) * dt);
    *g_half = Padded(R * geometry::RightJacobian(half_phi) * half_dt);
    return;
  }
  // Series in x2 = (t/2)^2 of c and of the coefficients a = (1 - cos s) / s^2,
  // b = (s - sin s) / s^3 of Jr at s = t/2.
  const double x2 = 0.25 * t2;
  const double c = 1.0 / 24.0 - x2 * (1.0 / 480.0 - x2 * (1.0 / 20160.0 - x2 / 1451520.0));
  const double a = 0.5 - x2 * (1.0 / 24.0 - x2 * (1.0 / 720.0 - x2 / 40320.0));
  const double b = 1.0 / 6.0 - x2 * (1.0 / 120.0 - x2 * (1.0 / 5040.0 - x2 / 362880.0));
  const Block R_outer = (R_mid * phi) * phi.transpose();
  *g_full = (dt * (1.0 - c * t2)) * R_mid + (dt * c) * R_outer;
  // Jr(phi/2) = (1 - b t^2/4) I - a/2 Hat(phi) + b/4 phi phi^T.
  *g_half = (half_dt * (1.0 - b * x2)) * R_mid - (half_dt * 0.5 * a) * TimesHat(R_mid, phi) +
            (half_dt * 0.25 * b) * R_outer;
}

}  // namespace

bool ImuSampleBetween(const ImuSamples& samples, int64_t after_ns, int64_t before_ns) {
  const auto first_after =
      std::upper_bound(samples.begin(), samples.end(), after_ns,
                       [](int64_t t, const ImuSample& sample) { return t < sample.t_ns; });
  return first_after != samples.end() && first_after->t_ns < before_ns;
}

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

GyroMean MeanGyro(const ImuSamples& samples, int64_t t0_ns, int64_t t1_ns) {
  auto it = std::lower_bound(samples.begin(), samples.end(), t0_ns,
                             [](const ImuSample& s, int64_t t) { return s.t_ns < t; });
  GyroMean mean;
  for (; it != samples.end() && it->t_ns <= t1_ns; ++it, ++mean.samples) {
    mean.rate_rad_s += it->gyro_rad_s;
  }
  if (mean.samples > 0) mean.rate_rad_s /= mean.samples;
  return mean;
}

GyroMean GyroAround(const ImuSamples& samples, int64_t t_ns, int64_t half_span_ns) {
  GyroMean gyro = MeanGyro(samples, t_ns - half_span_ns, t_ns + half_span_ns);
  if (gyro.samples == 0) gyro.rate_rad_s = InterpolateImu(samples, t_ns).gyro_rad_s;
  return gyro;
}

std::vector<GyroMean> GyroAroundOverLog(const ImuSamples& samples, int64_t period_ns,
                                        int64_t half_span_ns) {
  std::vector<GyroMean> out;
  if (samples.empty()) return out;
  for (int64_t t = samples.front().t_ns; t <= samples.back().t_ns; t += period_ns) {
    out.push_back(GyroAround(samples, t, half_span_ns));
  }
  return out;
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
  for (Block* block : {&cov_.tt, &cov_.vt, &cov_.vv, &cov_.pt, &cov_.pv, &cov_.pp, &cov_.tg,
                       &cov_.vg, &cov_.va, &cov_.pg, &cov_.pa}) {
    block->setZero();
  }
  cov_pending_half_dt_s_ = 0.0;
  var_bg_ = 0.0;
  var_ba_ = 0.0;
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
  // At most one step per sample interval; geometric growth keeps repeated calls amortized.
  // (Unsorted samples, rejected in the loop below, may give last < k.)
  const size_t last = LastAtOrBefore(samples, t_end_ns);
  const size_t max_steps = steps_.size() + (last > k ? last - k : 0) + 1;
  if (max_steps > steps_.capacity()) steps_.reserve(std::max(max_steps, 2 * steps_.capacity()));
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
      const bool in_dropout =
          noise_.max_sample_interval_s > 0.0 &&
          SecondsBetween(previous.t_ns, next.t_ns) > noise_.max_sample_interval_s;
      IntegrateStep(0.5 * (start.gyro_rad_s + end.gyro_rad_s),
                    0.5 * (start.accel_m_s2 + end.accel_m_s2), SecondsBetween(start.t_ns, end.t_ns),
                    in_dropout);
    }
    if (next.t_ns >= t_end_ns) break;
    previous = next;
  }
}

void ImuPreintegration::IntegrateStep(const Eigen::Vector3d& gyro_rad_s,
                                      const Eigen::Vector3d& accel_m_s2, double dt_s,
                                      bool in_dropout) {
  if (!(dt_s > 0.0) || !std::isfinite(dt_s)) {
    throw Error("IMU step length must be positive, got " + std::to_string(dt_s) + " s");
  }
  const Step step{gyro_rad_s, accel_m_s2, dt_s, in_dropout};
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
    const double half_dt = 0.5 * dt;
    // Sensitivities of the left rotation error to the rate over the step and its first half.
    const Block R_mid_block = Padded(R_mid);
    const Block g_v_accel = dt * R_mid_block;
    Block g_theta, g_half;
    StepRateJacobians(R_mid_block, dt * omega, dt, &g_theta, &g_half);
    // Eq. F4, gyro input to dv: -S g_half with S = Hat(u).
    const Block g_v_gyro = MinusHatTimes<4>(u, g_half);

    // Bias Jacobians, Eq. F6 (old values on the right-hand side).
    const Eigen::Matrix3d u_bg = MinusHatTimes<3>(u, d_theta_d_bg_ - g_half);
    const Eigen::Matrix3d g_v_accel_3 = dt * R_mid;
    d_p_d_bg_ += dt * d_v_d_bg_ + half_dt * u_bg;
    d_p_d_ba_ += dt * d_v_d_ba_ - half_dt * g_v_accel_3;
    d_v_d_bg_ += u_bg;
    d_v_d_ba_ -= g_v_accel_3;
    d_theta_d_bg_ -= g_theta;

    PropagateCovariance(u, g_theta, g_v_gyro, g_v_accel, dt, step.in_dropout);
  }

  delta_p_ += dt * delta_v_ + (0.5 * dt) * u;
  delta_v_ += u;
  delta_q_ = (q_mid * q_half).normalized();
  dt_s_ += dt;
}

// Covariance, Eq. F4: P <- A P A^T + G Qd G^T with
//   A = I + [0 0 0 | g_theta 0; -S 0 0 | g_v_gyro g_v_accel; -dt/2 S, dt I, 0 | ..; 0 | 0],
// the p rows of the input blocks being dt/2 times the v rows. Since the v error after the
// step (noise included) is v' = v - S dtheta + g_v_gyro db_g + g_v_accel db_a + n_v, the p row
// equals p' = p + dt/2 v + dt/2 v', so A splits into p += dt/2 v, the (dtheta, v) update, and
// p += dt/2 v again (deferred and merged with the next step's first): only the second needs
// 3x3 products. P = [D B; B^T C] is kept in blocks; the bias rows of A are identity, so
// C = diag(var_bg I, var_ba I) only gains the drift.
//
// On the (dtheta, v) rows, with A6 = [I 0; -S I] and H = [g_theta 0; g_v_gyro g_v_accel] the
// bias inputs, the white-noise inputs equal H (the noise enters like a bias over one step), so
//   D66 <- A6 D66 A6^T + A6 B6 H^T + H B6^T A6^T + H (C + Qd) H^T = A6 D66 A6^T + X H^T + H X^T
// with X = A6 B6 + H (C + Qd) / 2: the one product X H^T covers both the bias coupling and
// the noise, and its sum with its transpose is symmetric by construction. The accelerometer
// noise stays apart since it is rotation invariant: g_v_accel (sa^2/dt) g_v_accel^T =
// sa^2 dt I. The dtheta-b_a block of B is zero (the dtheta row of A has no b_a input), which
// removes one 3x3 product. Every product is written as X Y^T or X Hat(u), column
// combinations of a padded Block X, using the lower blocks of D and transposing where the
// other side is needed (Eigen's GEMM path costs more at this size, and its 3-row columns do
// not vectorize).
void ImuPreintegration::PropagateCovariance(const Eigen::Vector3d& u, const Block& g_theta,
                                            const Block& g_v_gyro, const Block& g_v_accel,
                                            double dt, bool in_dropout) {
  CovarianceBlocks& c = cov_;
  // The second p += dt/2 v of the previous step is still pending; v has not changed since.
  const double h = cov_pending_half_dt_s_ + 0.5 * dt;
  const Block h_pv = h * c.pv;
  c.pp += (h_pv + Transposed(h_pv)) + (h * h) * c.vv;
  c.pt += h * c.vt;
  c.pv += h * c.vv;
  c.pg += h * c.vg;
  c.pa += h * c.va;

  // (A6 B6) on the v rows; the dtheta rows of A6 are identity.
  const Block AB_vg = c.vg + MinusHatTimes<4>(u, c.tg);

  // p rows, final for this step: D_p6 A6^T + B_p H^T (the p-p block was final above).
  const Block new_pt = c.pt + TimesTransposed(c.pg, g_theta);
  const Block new_pv =
      c.pv + TimesHat(c.pt, u) + TimesTransposed(c.pg, g_v_gyro) + TimesTransposed(c.pa, g_v_accel);

  // X = A6 B6 + H (C + Qd) / 2, Qd = sg^2/dt for the gyro (Eq. F5). In a dropout the rate's
  // and the specific force's errors off the interpolated line, held over the step, add their
  // variances as they are (Eq. F5b): the rate's to Qd, the force's sd^2 dt^2 to the v-v block.
  const double dropout_gyro_var =
      in_dropout ? noise_.dropout_gyro_sigma_rad_s * noise_.dropout_gyro_sigma_rad_s : 0.0;
  const double dropout_accel_var =
      in_dropout ? noise_.dropout_accel_sigma_m_s2 * noise_.dropout_accel_sigma_m_s2 : 0.0;
  const double qg =
      noise_.gyroscope_noise_density * noise_.gyroscope_noise_density / dt + dropout_gyro_var;
  const double sa2_dt =
      noise_.accelerometer_noise_density * noise_.accelerometer_noise_density * dt +
      dropout_accel_var * dt * dt;
  const double cg = 0.5 * (var_bg_ + qg);
  const Block X_tg = c.tg + cg * g_theta;
  const Block X_vg = AB_vg + cg * g_v_gyro;
  const Block X_va = c.va + (0.5 * var_ba_) * g_v_accel;
  // Blocks of X H^T; the dtheta-v one transposed, (X_tg G_vg^T)^T = G_vg X_tg^T, since the
  // v-dtheta block is the one kept.
  const Block M_tt = TimesTransposed(X_tg, g_theta);
  const Block M_vt = TimesTransposed(X_vg, g_theta);
  const Block M_tv_T = TimesTransposed(g_v_gyro, X_tg);
  // A6 D66 A6^T: the v-dtheta block gains (D_tt S)^T = -S D_tt, the v-v block
  // S D_tt S^T = (-S D_tt) S and -S D_tv - D_vt S^T, whose sum with its transpose is formed
  // from D_vt S = (-S D_tv)^T together with the X H^T terms.
  const Block minus_S_D_tt = Transposed(TimesHat(c.tt, u));
  Block W_vv = TimesHat(c.vt, u);
  W_vv += TimesTransposed(X_vg, g_v_gyro) + TimesTransposed(X_va, g_v_accel);

  c.tt += M_tt + Transposed(M_tt);
  c.vt += minus_S_D_tt + M_tv_T + M_vt;
  c.vv += TimesHat(minus_S_D_tt, u) + (W_vv + Transposed(W_vv));
  c.vv.diagonal().array() += sa2_dt;
  c.pt = new_pt;
  c.pv = new_pv;

  // B6 <- A6 B6 + H C; the p rows of B are unchanged until the deferred p += dt/2 v.
  c.tg += var_bg_ * g_theta;
  c.vg = AB_vg + var_bg_ * g_v_gyro;
  c.va += var_ba_ * g_v_accel;

  cov_pending_half_dt_s_ = 0.5 * dt;
  // The bias random walk adds s_w^2 dt per step.
  const double bg = noise_.gyroscope_random_walk;
  const double ba = noise_.accelerometer_random_walk;
  var_bg_ += bg * bg * dt;
  var_ba_ += ba * ba * dt;
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
  return delta_q_.conjugate().toRotationMatrix() * d_theta_d_bg_.topRows<3>();
}

LinearizedDeltas ImuPreintegration::Linearized() const {
  LinearizedDeltas out;
  out.delta_q = delta_q_;
  out.delta_v = delta_v_;
  out.delta_p = delta_p_;
  out.d_R_d_bg = d_R_d_bg();
  out.d_v_d_bg = d_v_d_bg_;
  out.d_v_d_ba = d_v_d_ba_;
  out.d_p_d_bg = d_p_d_bg_;
  out.d_p_d_ba = d_p_d_ba_;
  out.b_g_lin = b_g_lin_;
  out.b_a_lin = b_a_lin_;
  return out;
}

// Left to right rotation error: dphi = dR^T dtheta; the other components are unchanged.
Matrix15d ImuPreintegration::Covariance() const {
  const Eigen::Matrix3d Rt = delta_q_.conjugate().toRotationMatrix();
  const CovarianceBlocks& c = cov_;
  Eigen::Matrix<double, 9, 9> D;
  D.block<3, 3>(0, 0) = c.tt.topRows<3>();
  D.block<3, 3>(3, 0) = c.vt.topRows<3>();
  D.block<3, 3>(3, 3) = c.vv.topRows<3>();
  D.block<3, 3>(6, 0) = c.pt.topRows<3>();
  D.block<3, 3>(6, 3) = c.pv.topRows<3>();
  D.block<3, 3>(6, 6) = c.pp.topRows<3>();
  D.block<3, 3>(0, 3) = c.vt.topRows<3>().transpose();
  D.block<6, 3>(0, 6) = D.block<3, 6>(6, 0).transpose();
  Eigen::Matrix<double, 9, 6> B;
  B << c.tg.topRows<3>(), Eigen::Matrix3d::Zero(), c.vg.topRows<3>(), c.va.topRows<3>(),
      c.pg.topRows<3>(), c.pa.topRows<3>();
  AddVelocityToPosition(cov_pending_half_dt_s_, &D, &B);
  Matrix15d cov;
  cov.topLeftCorner<9, 9>() = D;
  cov.topRightCorner<9, 6>() = B;
  cov.bottomLeftCorner<6, 9>() = B.transpose();
  cov.bottomRightCorner<6, 6>().setZero();
  cov.diagonal().segment<3>(9).setConstant(var_bg_);
  cov.diagonal().segment<3>(12).setConstant(var_ba_);
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
  CorrectedDeltas<double>(b_g, b_a, dq, dv, dp);
}

}  // namespace sensors
}  // namespace autocal
