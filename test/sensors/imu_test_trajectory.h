#pragma once

// Closed-form trajectories of the IMU frame and the exact IMU data they produce, for tests
// of preintegration and of the factors built on it.
//   R(t) = Exp(phi(t)),  body rate omega_I = Jr(phi) phi_dot  (R_dot = R Hat(omega_I)),
//   specific force f_I = R^T (p_ddot - g_W).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "autocal/common/time.h"
#include "autocal/geometry/se3.h"
#include "autocal/geometry/so3.h"
#include "autocal/sensors/imu_preintegration.h"
#include "autocal/sensors/measurements.h"

namespace autocal {
namespace test {

class ImuTrajectory {
 public:
  virtual ~ImuTrajectory() = default;
  virtual Eigen::Quaterniond q_W_I(double t) const = 0;
  virtual Eigen::Vector3d p_W_I(double t) const = 0;
  virtual Eigen::Vector3d v_W_I(double t) const = 0;
  virtual Eigen::Vector3d a_W_I(double t) const = 0;
  virtual Eigen::Vector3d omega_I(double t) const = 0;

  Eigen::Vector3d SpecificForce(double t, const Eigen::Vector3d& g_W) const {
    return q_W_I(t).conjugate() * (a_W_I(t) - g_W);
  }
  sensors::NavStated State(double t) const {
    sensors::NavStated s;
    s.q_W_I = q_W_I(t);
    s.p_W_I = p_W_I(t);
    s.v_W_I = v_W_I(t);
    return s;
  }
};

// T(t) = T0 Exp([v_body; omega] t): constant body rate and body velocity.
class ConstantTwistTrajectory final : public ImuTrajectory {
 public:
  ConstantTwistTrajectory(const geometry::Pose3d& T0, const Eigen::Vector3d& v_body,
                          const Eigen::Vector3d& omega)
      : T0_(T0), v_body_(v_body), omega_(omega) {}
  Eigen::Quaterniond q_W_I(double t) const override {
    return T0_.q * geometry::Exp(Eigen::Vector3d(omega_ * t));
  }
  Eigen::Vector3d p_W_I(double t) const override {
    geometry::Vector6<double> xi;
    xi << v_body_ * t, omega_ * t;
    return (T0_ * geometry::ExpSE3(xi)).p;
  }
  Eigen::Vector3d v_W_I(double t) const override { return q_W_I(t) * v_body_; }
  Eigen::Vector3d a_W_I(double t) const override { return q_W_I(t) * omega_.cross(v_body_); }
  Eigen::Vector3d omega_I(double /*t*/) const override { return omega_; }

 private:
  geometry::Pose3d T0_;
  Eigen::Vector3d v_body_;
  Eigen::Vector3d omega_;
};

// Each of position and rotation vector is c0 + c1 t + c2 t^2 + sum_k A_k sin(w_k t + ph_k)
// (per axis), differentiated exactly.
class SmoothTrajectory final : public ImuTrajectory {
 public:
  struct Curve {
    Eigen::Vector3d c0 = Eigen::Vector3d::Zero();
    Eigen::Vector3d c1 = Eigen::Vector3d::Zero();
    Eigen::Vector3d c2 = Eigen::Vector3d::Zero();
    std::vector<Eigen::Vector3d> amplitude;
    std::vector<Eigen::Vector3d> frequency_rad_s;
    std::vector<Eigen::Vector3d> phase;

    Eigen::Vector3d Derivative(double t, int order) const {
      Eigen::Vector3d out = Eigen::Vector3d::Zero();
      if (order == 0) out = c0 + c1 * t + c2 * t * t;
      if (order == 1) out = c1 + 2.0 * c2 * t;
      if (order == 2) out = 2.0 * c2;
      for (size_t k = 0; k < amplitude.size(); ++k) {
        for (int i = 0; i < 3; ++i) {
          const double w = frequency_rad_s[k](i);
          const double arg = w * t + phase[k](i);
          const double a = amplitude[k](i);
          if (order == 0) out(i) += a * std::sin(arg);
          if (order == 1) out(i) += a * w * std::cos(arg);
          if (order == 2) out(i) -= a * w * w * std::sin(arg);
        }
      }
      return out;
    }
  };

  SmoothTrajectory(Curve position, Curve rotation)
      : position_(std::move(position)), rotation_(std::move(rotation)) {}

  // Random sums of sinusoids: position amplitudes ~pos_scale m, rotation ~rot_scale rad,
  // frequencies 0.5-3 rad/s, plus a forward drive.
  static SmoothTrajectory Random(uint32_t seed, double pos_scale = 2.0, double rot_scale = 0.6) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    auto random_vec = [&](double s) { return Eigen::Vector3d(s * u(rng), s * u(rng), s * u(rng)); };
    auto random_curve = [&](double scale) {
      Curve c;
      c.c0 = random_vec(scale);
      c.c1 = random_vec(scale);
      for (int k = 0; k < 3; ++k) {
        c.amplitude.push_back(random_vec(scale));
        c.frequency_rad_s.push_back(random_vec(1.25) + Eigen::Vector3d::Constant(1.75));
        c.phase.push_back(random_vec(3.0));
      }
      return c;
    };
    return SmoothTrajectory(random_curve(pos_scale), random_curve(rot_scale));
  }

  Eigen::Quaterniond q_W_I(double t) const override {
    return geometry::Exp(rotation_.Derivative(t, 0));
  }
  Eigen::Vector3d p_W_I(double t) const override { return position_.Derivative(t, 0); }
  Eigen::Vector3d v_W_I(double t) const override { return position_.Derivative(t, 1); }
  Eigen::Vector3d a_W_I(double t) const override { return position_.Derivative(t, 2); }
  Eigen::Vector3d omega_I(double t) const override {
    return geometry::RightJacobian(rotation_.Derivative(t, 0)) * rotation_.Derivative(t, 1);
  }

 private:
  Curve position_;
  Curve rotation_;
};

// Noise-free samples at t0_ns + k period_ns for k = 0..count-1 (times relative to t = 0 at
// t_ns = 0), with constant biases added.
inline sensors::ImuSamples SampleImu(const ImuTrajectory& trajectory, int64_t t0_ns,
                                     int64_t period_ns, int count, const Eigen::Vector3d& g_W,
                                     const Eigen::Vector3d& b_g = Eigen::Vector3d::Zero(),
                                     const Eigen::Vector3d& b_a = Eigen::Vector3d::Zero()) {
  sensors::ImuSamples samples(count);
  for (int k = 0; k < count; ++k) {
    const int64_t t_ns = t0_ns + k * period_ns;
    const double t = NsToSeconds(t_ns);
    samples[k].t_ns = t_ns;
    samples[k].gyro_rad_s = trajectory.omega_I(t) + b_g;
    samples[k].accel_m_s2 = trajectory.SpecificForce(t, g_W) + b_a;
  }
  return samples;
}

// One Monte Carlo draw of `clean` samples `period_s` apart as a real IMU reads them: white noise
// of the densities of `noise` (sigma / sqrt(period) per sample) and biases that start at zero
// and random-walk from sample to sample; `gauss()` gives a standard normal 3-vector. *b_g and
// *b_a are the biases at the last sample.
template <typename Gauss>
sensors::ImuSamples NoisyDraw(const sensors::ImuSamples& clean, double period_s,
                              const sensors::ImuNoise& noise, Gauss&& gauss, Eigen::Vector3d* b_g,
                              Eigen::Vector3d* b_a) {
  sensors::ImuSamples noisy = clean;
  b_g->setZero();
  b_a->setZero();
  for (size_t k = 0; k < noisy.size(); ++k) {
    noisy[k].gyro_rad_s += *b_g + noise.gyroscope_noise_density / std::sqrt(period_s) * gauss();
    noisy[k].accel_m_s2 += *b_a + noise.accelerometer_noise_density / std::sqrt(period_s) * gauss();
    if (k + 1 < noisy.size()) {
      *b_g += noise.gyroscope_random_walk * std::sqrt(period_s) * gauss();
      *b_a += noise.accelerometer_random_walk * std::sqrt(period_s) * gauss();
    }
  }
  return noisy;
}

// The exact preintegrated deltas between t_i and t_j (Eq. F1 of docs/factors.md).
struct TrueDeltas {
  Eigen::Quaterniond dq;
  Eigen::Vector3d dv;
  Eigen::Vector3d dp;
};

inline TrueDeltas ExactDeltas(const ImuTrajectory& trajectory, double t_i, double t_j,
                              const Eigen::Vector3d& g_W) {
  const double dt = t_j - t_i;
  const Eigen::Quaterniond q_i = trajectory.q_W_I(t_i);
  const Eigen::Vector3d v_i = trajectory.v_W_I(t_i);
  TrueDeltas d;
  d.dq = q_i.conjugate() * trajectory.q_W_I(t_j);
  d.dv = q_i.conjugate() * (trajectory.v_W_I(t_j) - v_i - g_W * dt);
  d.dp = q_i.conjugate() *
         (trajectory.p_W_I(t_j) - trajectory.p_W_I(t_i) - v_i * dt - 0.5 * g_W * dt * dt);
  return d;
}

}  // namespace test
}  // namespace autocal
