#include "autocal/estimation/mount_initialization.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <string>

#include "autocal/common/error.h"
#include "autocal/common/format.h"
#include "autocal/common/time.h"
#include "autocal/common/units.h"
#include "autocal/geometry/quaternion_plus.h"
#include "autocal/geometry/so3.h"

namespace autocal {
namespace estimation {

namespace {

// Mean specific force over the samples that `use` accepts; the count in *n.
template <typename Use>
Eigen::Vector3d MeanSpecificForce(const sensors::ImuSamples& imu, Use use, size_t* n,
                                  double* span_s) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  *n = 0;
  int64_t first_ns = 0, last_ns = 0;
  for (const sensors::ImuSample& s : imu) {
    if (!use(s)) continue;
    sum += s.accel_m_s2;
    if (*n == 0) first_ns = s.t_ns;
    last_ns = s.t_ns;
    ++*n;
  }
  *span_s = SecondsBetween(first_ns, last_ns);
  return *n > 0 ? Eigen::Vector3d(sum / static_cast<double>(*n)) : Eigen::Vector3d::Zero();
}

// One row of the horizontal fit: the measured horizontal specific force and the modelled
// (forward, left) acceleration, both as means over one window, in the plane's 2-D basis.
struct FitRow {
  Eigen::Vector2d measured;
  Eigen::Vector2d modelled;  // (dv/dt, v * omega)
  // omega^2 and d(omega)/dt: a lever arm r (forward, left) from the point the speed refers
  // to adds (-omega^2 r_x - omega' r_y, omega' r_x - omega^2 r_y).
  double rate_sq = 0.0;
  double rate_change = 0.0;
};

std::vector<FitRow> HorizontalFitRows(const sensors::ImuSamples& imu, const ScalarSeries& speed,
                                      const Eigen::Vector3d& up_I, const Eigen::Vector3d& e1,
                                      const Eigen::Vector3d& e2, double window_s) {
  std::vector<FitRow> rows;
  const int64_t begin_ns = std::max(imu.front().t_ns, speed.front().t_ns);
  const int64_t end_ns = std::min(imu.back().t_ns, speed.back().t_ns);
  const int64_t window_ns = SecondsToNs(window_s);
  size_t i = 0;
  for (int64_t a = begin_ns; a + window_ns <= end_ns; a += window_ns) {
    const int64_t b = a + window_ns;
    while (i < imu.size() && imu[i].t_ns < a) ++i;
    Eigen::Vector3d force = Eigen::Vector3d::Zero();
    double centripetal = 0.0, rate_sq = 0.0;
    size_t n = 0;
    for (size_t k = i; k < imu.size() && imu[k].t_ns < b; ++k, ++n) {
      const double rate = up_I.dot(imu[k].gyro_rad_s);
      force += imu[k].accel_m_s2;
      centripetal += InterpolateSeries(speed, imu[k].t_ns) * rate;
      rate_sq += rate * rate;
    }
    if (n < 3) continue;
    // The rate change over the window from the mean rates of its two halves.
    const size_t half = n / 2;
    double first = 0.0, second = 0.0;
    for (size_t k = 0; k < n; ++k) (k < half ? first : second) += up_I.dot(imu[i + k].gyro_rad_s);
    const double rate_change =
        (second / static_cast<double>(n - half) - first / static_cast<double>(half)) /
        (0.5 * window_s);
    force /= static_cast<double>(n);
    const double dv_dt = (InterpolateSeries(speed, b) - InterpolateSeries(speed, a)) / window_s;
    rows.push_back({Eigen::Vector2d(e1.dot(force), e2.dot(force)),
                    Eigen::Vector2d(dv_dt, centripetal / static_cast<double>(n)),
                    rate_sq / static_cast<double>(n), rate_change});
  }
  return rows;
}

Eigen::Vector2d MeanOf(const std::vector<FitRow>& rows, Eigen::Vector2d FitRow::*member) {
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  for (const FitRow& r : rows) sum += r.*member;
  return sum / static_cast<double>(rows.size());
}

// The least-squares rotation angle psi in measured = R(psi) modelled + constant (the
// constant absorbs the accelerometer bias and a mean ground slope), with its quality.
struct PlanarFit {
  double psi_rad = 0.0;
  double sigma_rad = 0.0;
  double correlation = 0.0;
  double excitation_m_s2 = 0.0;
  Eigen::Vector2d lever_arm_m = Eigen::Vector2d::Zero();  // (forward, left)
};

PlanarFit FitPlanarRotation(const std::vector<FitRow>& rows) {
  // Unknowns x = (c, s, r1, r2, b1, b2): R(psi) = [c -s; s c], the lever arm r and the bias b.
  const size_t n = rows.size();
  Eigen::MatrixXd A(2 * n, 6);
  Eigen::VectorXd y(2 * n);
  for (size_t i = 0; i < n; ++i) {
    const FitRow& r = rows[i];
    const Eigen::Vector2d& m = r.modelled;
    const Eigen::Index k = static_cast<Eigen::Index>(2 * i);
    A.row(k) << m.x(), -m.y(), -r.rate_sq, -r.rate_change, 1.0, 0.0;
    A.row(k + 1) << m.y(), m.x(), r.rate_change, -r.rate_sq, 0.0, 1.0;
    y.segment<2>(k) = r.measured;
  }
  // Huber re-weighting per window: bumps and knocks of a rough ground are heavy-tailed.
  Eigen::VectorXd w = Eigen::VectorXd::Ones(2 * n);
  Eigen::VectorXd x;
  Eigen::MatrixXd normal;
  for (int iteration = 0; iteration < 4; ++iteration) {
    normal = A.transpose() * w.asDiagonal() * A;
    x = normal.ldlt().solve(A.transpose() * w.asDiagonal() * y);
    const Eigen::VectorXd res = y - A * x;
    const double sigma = std::sqrt(res.squaredNorm() / static_cast<double>(2 * n));
    for (size_t i = 0; i < n; ++i) {
      const double e = res.segment<2>(static_cast<Eigen::Index>(2 * i)).norm();
      const double wi = e <= 1.5 * sigma ? 1.0 : 1.5 * sigma / e;
      w.segment<2>(static_cast<Eigen::Index>(2 * i)).setConstant(wi);
    }
  }
  PlanarFit fit;
  fit.psi_rad = std::atan2(x(1), x(0));
  const double residual_sq = (y - A * x).squaredNorm();
  const double weighted_sq = (y - A * x).cwiseAbs2().dot(w);
  double mm = 0.0, ff = 0.0;
  const Eigen::Vector2d mean_f = MeanOf(rows, &FitRow::measured);
  const Eigen::Vector2d mean_m = MeanOf(rows, &FitRow::modelled);
  for (const FitRow& r : rows) {
    mm += (r.modelled - mean_m).squaredNorm();
    ff += (r.measured - mean_f).squaredNorm();
  }
  fit.excitation_m_s2 = std::sqrt(mm / static_cast<double>(n));
  fit.correlation = ff > 0.0 ? std::sqrt(std::max(0.0, 1.0 - residual_sq / ff)) : 0.0;
  // The angle's variance: the (c, s) covariance along the tangent of the circle.
  const double scale = x.head<2>().norm();
  const double variance = weighted_sq / std::max(1.0, 2.0 * static_cast<double>(n) - 6.0);
  const Eigen::MatrixXd covariance = variance * normal.inverse();
  const Eigen::Vector2d tangent(-x(1) / scale, x(0) / scale);
  fit.sigma_rad = scale > 0.0
                      ? std::sqrt(tangent.dot(covariance.topLeftCorner<2, 2>() * tangent)) / scale
                      : M_PI;
  fit.lever_arm_m = Eigen::Rotation2Dd(-fit.psi_rad) * x.segment<2>(2);
  return fit;
}

}  // namespace

UpAxisEstimate EstimateUpAxis(const sensors::ImuSamples& imu,
                              const MountInitializationOptions& options) {
  UpAxisEstimate out;
  if (imu.size() < 10) {
    out.problem = "too few IMU samples for the up axis (" + std::to_string(imu.size()) + ")";
    return out;
  }
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  const StillStart still = DetectStillStart(imu, options.still);
  if (still.found) {
    mean = MeanSpecificForce(
        imu,
        [&](const sensors::ImuSample& s) {
          return s.t_ns >= still.t_begin_ns && s.t_ns <= still.t_end_ns;
        },
        &out.samples, &out.span_s);
    out.source = "the still period " +
                 FormatFixed(SecondsBetween(imu.front().t_ns, still.t_begin_ns), 1) + "-" +
                 FormatFixed(SecondsBetween(imu.front().t_ns, still.t_end_ns), 1) + " s";
  } else {
    mean = MeanSpecificForce(
        imu,
        [&](const sensors::ImuSample& s) {
          return s.gyro_rad_s.norm() <= options.max_low_dynamics_rate_rad_s;
        },
        &out.samples, &out.span_s);
    out.source = std::to_string(out.samples) + " samples turning slower than " +
                 FormatFixed(options.max_low_dynamics_rate_rad_s, 3) + " rad/s";
    if (out.samples < imu.size() / 10) {
      mean = MeanSpecificForce(
          imu, [](const sensors::ImuSample&) { return true; }, &out.samples, &out.span_s);
      out.source = "all " + std::to_string(out.samples) + " samples";
    }
  }
  out.specific_force_m_s2 = mean.norm();
  if (!(out.specific_force_m_s2 > 0.0)) {
    out.problem = "the mean specific force is zero: no gravity in the accelerometer";
    return out;
  }
  out.up_I = mean / out.specific_force_m_s2;
  if (std::abs(out.specific_force_m_s2 - options.gravity_m_s2) > options.max_gravity_error_m_s2) {
    out.problem = "the mean specific force over " + out.source + " is " +
                  FormatFixed(out.specific_force_m_s2, 3) + " m/s^2, not gravity (" +
                  FormatFixed(options.gravity_m_s2, 3) +
                  "): is the accelerometer in m/s^2 (not g)?";
    return out;
  }
  out.ok = true;
  return out;
}

MountInitialization InitializeMount(const sensors::ImuSamples& imu,
                                    const ScalarSeries& wheel_speed_m_s, double wheel_time_offset_s,
                                    const MountInitializationOptions& options) {
  if (!(options.window_s > 0.0 && options.window_s <= kMaxMountWindowS)) {
    throw Error("InitializeMount: window_s must lie in (0, " + FormatShort(kMaxMountWindowS) +
                "] s, got " + FormatShort(options.window_s));
  }
  MountInitialization out;
  out.up = EstimateUpAxis(imu, options);
  if (!out.up.ok) out.problems.push_back(out.up.problem);
  const Eigen::Vector3d& up = out.up.up_I;
  out.q_I_V = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), up);
  if (wheel_speed_m_s.size() < 2 || imu.size() < 10) {
    out.problems.push_back("no wheel speed to find the forward axis");
    return out;
  }
  const Eigen::Vector3d e1 = up.unitOrthogonal();
  const Eigen::Vector3d e2 = up.cross(e1);
  const std::vector<FitRow> rows = HorizontalFitRows(
      imu, Shifted(wheel_speed_m_s, wheel_time_offset_s), up, e1, e2, options.window_s);
  out.windows = rows.size();
  if (rows.size() < 10) {
    out.problems.push_back("the IMU and the wheel speed overlap for only " +
                           std::to_string(rows.size()) + " windows of " +
                           FormatFixed(options.window_s, 2) + " s (need 10)");
    return out;
  }
  const PlanarFit fit = FitPlanarRotation(rows);
  out.forward_I = std::cos(fit.psi_rad) * e1 + std::sin(fit.psi_rad) * e2;
  out.yaw_sigma_deg = fit.sigma_rad * kRadToDeg;
  out.fit_correlation = fit.correlation;
  out.excitation_m_s2 = fit.excitation_m_s2;
  out.lever_arm_m = fit.lever_arm_m;
  if (fit.excitation_m_s2 < options.min_excitation_m_s2) {
    out.problems.push_back("the drive barely accelerates or turns (rms " +
                           FormatFixed(fit.excitation_m_s2, 3) + " m/s^2 of horizontal " +
                           "acceleration, need " + FormatFixed(options.min_excitation_m_s2, 3) +
                           "): the forward axis is not determined");
  } else if (fit.correlation < options.min_fit_correlation) {
    out.problems.push_back(
        "the horizontal specific force follows the wheel speed poorly "
        "(correlation " +
        FormatFixed(fit.correlation, 2) + ", need " + FormatFixed(options.min_fit_correlation, 2) +
        "): is the speed on the right clock and signed?");
  } else if (out.yaw_sigma_deg > options.max_yaw_sigma_deg) {
    out.problems.push_back("the forward axis is uncertain by " + FormatFixed(out.yaw_sigma_deg, 1) +
                           " deg about the up axis (limit " +
                           FormatFixed(options.max_yaw_sigma_deg, 1) + ")");
  } else {
    out.forward_found = true;
    Eigen::Matrix3d R_I_V;
    R_I_V << out.forward_I, up.cross(out.forward_I), up;
    out.q_I_V = Eigen::Quaterniond(R_I_V).normalized();
  }
  out.ok = out.up.ok && out.forward_found;
  return out;
}

MountPrior FuseUpAxis(const MountPrior& prior, const Eigen::Vector3d& up_I, double up_sigma_rad) {
  if (!(up_sigma_rad > 0.0) || !std::isfinite(up_sigma_rad) || !up_I.allFinite() ||
      !(up_I.norm() > 0.0)) {
    throw Error("FuseUpAxis: the up axis needs a positive finite sigma and a nonzero direction");
  }
  const Eigen::Vector3d up_V = prior.q_I_V.conjugate() * up_I.normalized();
  const Eigen::Vector3d delta_g =
      geometry::Log(Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), up_V));
  MountPrior fused = prior;
  Eigen::Vector3d delta = Eigen::Vector3d::Zero();
  const double g2 = up_sigma_rad * up_sigma_rad;
  for (int i = 0; i < 2; ++i) {
    const double p2 = prior.sigma_rad(i) * prior.sigma_rad(i);
    delta(i) = p2 / (p2 + g2) * delta_g(i);
    fused.sigma_rad(i) = std::sqrt(p2 * g2 / (p2 + g2));
  }
  fused.q_I_V = geometry::QuaternionPlus(prior.q_I_V, delta);
  return fused;
}

}  // namespace estimation
}  // namespace autocal
