#include "estimation/time_offset_factors.h"

#include <ceres/ceres.h>
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/time.h"
#include "autocal/geometry/manifolds.h"
#include "estimation/keyframe_interpolation.h"
#include "factors/factor_test_utils.h"

namespace autocal {
namespace estimation {
namespace {

using internal::CarriedState;
using internal::CarryPosition;
using internal::CarryState;
using internal::ImuAround;
using internal::ImuAroundKeyframe;
using internal::ShiftedGnssResidual;
using internal::ShiftedWheelForm;
using internal::ShiftedWheelResidual;

constexpr int64_t kStartNs = 1'700'000'000'000'000'000;
constexpr double kGravity = 9.81;

int64_t StampNs(double t_s) { return kStartNs + static_cast<int64_t>(std::llround(t_s * 1e9)); }

// A motion Eq. K16 carries exactly: the IMU turns about one axis u (in I) at a rate that changes
// linearly, R(t) = R0 Exp(u (w0 t + w1 t^2 / 2)), and moves at a constant acceleration,
// p(t) = p0 + v0 t + a t^2 / 2, with biases b_g, b_a.
struct FixedAxisMotion {
  Eigen::Quaterniond q0 = Eigen::Quaterniond::Identity();
  Eigen::Vector3d u = Eigen::Vector3d::UnitZ();
  double w0 = 0.0, w1 = 0.0;
  Eigen::Vector3d p0 = Eigen::Vector3d::Zero(), v0 = Eigen::Vector3d::Zero();
  Eigen::Vector3d a = Eigen::Vector3d::Zero();
  Eigen::Vector3d b_g = Eigen::Vector3d::Zero(), b_a = Eigen::Vector3d::Zero();
  Eigen::Vector3d g_W{0.0, 0.0, -kGravity};

  Eigen::Quaterniond Q(double t) const {
    return q0 * Eigen::Quaterniond(Eigen::AngleAxisd(w0 * t + 0.5 * w1 * t * t, u));
  }
  Eigen::Vector3d P(double t) const { return p0 + v0 * t + 0.5 * a * t * t; }
  Eigen::Vector3d V(double t) const { return v0 + a * t; }
  Eigen::Vector3d Rate(double t) const { return u * (w0 + w1 * t); }  // bias-corrected

  // The readings at t: the raw gyro, its slope and the raw specific force.
  ImuAroundKeyframe Imu(double t) const {
    ImuAroundKeyframe imu;
    imu.gyro_rad_s = Rate(t) + b_g;
    imu.gyro_slope_rad_s2 = u * w1;
    imu.accel_m_s2 = Q(t).conjugate() * (a - g_W) + b_a;
    imu.g_W = g_W;
    return imu;
  }
  // Keyframe blocks at t.
  struct State {
    Eigen::Quaterniond q;
    Eigen::Vector3d p, v, b_g, b_a;
  };
  State At(double t) const { return {Q(t), P(t), V(t), b_g, b_a}; }
};

FixedAxisMotion RandomMotion(std::mt19937* rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const auto vec = [&](double scale) -> Eigen::Vector3d {
    return Eigen::Vector3d(u(*rng), u(*rng), u(*rng)) * scale;
  };
  FixedAxisMotion m;
  m.q0 = Eigen::Quaterniond::UnitRandom();
  m.u = vec(1.0).normalized();
  m.w0 = 0.5 * u(*rng);
  m.w1 = 0.3 * u(*rng);
  m.p0 = vec(50.0);
  m.v0 = vec(8.0);
  m.a = vec(2.0);
  m.b_g = vec(0.01);
  m.b_a = vec(0.1);
  return m;
}

TEST(CarryState, IsExactForAFixedAxisTurnAtConstantAcceleration) {
  std::mt19937 rng(3);
  for (int trial = 0; trial < 10; ++trial) {
    const FixedAxisMotion m = RandomMotion(&rng);
    const double t_k = 4.0;
    FixedAxisMotion::State k = m.At(t_k);
    for (const double delta : {-0.3, -0.02, 0.0, 0.01, 0.25}) {
      const CarriedState<double> s = CarryState(k.q.coeffs().data(), k.v.data(), k.b_g.data(),
                                                k.b_a.data(), m.Imu(t_k), delta);
      const std::string at = "trial " + std::to_string(trial) + " delta " + std::to_string(delta);
      EXPECT_LT(s.q_W_I.angularDistance(m.Q(t_k + delta)), 1e-12) << at;
      EXPECT_LT((CarryPosition(k.p.data(), k.v.data(), s, delta) - m.P(t_k + delta)).norm(), 1e-9)
          << at;
      EXPECT_LT((s.v_W_I - m.V(t_k + delta)).norm(), 1e-12) << at;
      EXPECT_LT((s.w_I - m.Rate(t_k + delta)).norm(), 1e-12) << at;
    }
  }
}

// The fix stamped t_j on the receiver's clock holds the antenna at IMU time t_j + offset.
factors::GnssMeasurement FixAt(const FixedAxisMotion& m, const Eigen::Vector3d& p_I_A,
                               double t_imu_s) {
  factors::GnssMeasurement fix;
  fix.p_W_A = m.P(t_imu_s) + m.Q(t_imu_s) * p_I_A;
  fix.sigma_enu_m = Eigen::Vector3d(0.02, 0.03, 0.05);
  return fix;
}

TEST(ShiftedGnssResidual, VanishesAtTheTrueOffsetAndNotAtZero) {
  std::mt19937 rng(5);
  const double offset_s = -0.21;  // the receiver stamps 0.21 s after the fix
  const Eigen::Vector3d p_I_A(0.3, -0.1, 0.7);
  for (int trial = 0; trial < 10; ++trial) {
    FixedAxisMotion m = RandomMotion(&rng);
    m.w0 = m.w1 = 0.0;  // the antenna's rotation is checked by CarryState
    const double t_k = 3.0, t_fix = t_k + 0.03 - offset_s;
    FixedAxisMotion::State k = m.At(t_k);
    const ShiftedGnssResidual residual(FixAt(m, p_I_A, t_fix + offset_s), StampNs(t_fix),
                                       StampNs(t_k), m.Imu(t_k), factors::GnssAxes::kAll);
    Eigen::Vector3d r;
    ASSERT_TRUE(residual(k.q.coeffs().data(), k.p.data(), k.v.data(), k.b_g.data(), k.b_a.data(),
                         p_I_A.data(), &offset_s, r.data()));
    EXPECT_LT(r.norm(), 1e-6) << "trial " << trial;  // 1e-6 sigma: the stamps' rounding
    // Without the offset the state is carried to t_fix instead: the antenna 0.21 s later.
    const double zero = 0.0;
    ASSERT_TRUE(residual(k.q.coeffs().data(), k.p.data(), k.v.data(), k.b_g.data(), k.b_a.data(),
                         p_I_A.data(), &zero, r.data()));
    const Eigen::Vector3d expected =
        (m.P(t_fix) - m.P(t_fix + offset_s)).cwiseQuotient(Eigen::Vector3d(0.02, 0.03, 0.05));
    EXPECT_LT((r - expected).norm(), 1e-6) << "trial " << trial;
    EXPECT_GT(r.norm(), 1.0);
  }
}

std::vector<const ceres::Manifold*> WithQuaternions(size_t blocks, std::vector<size_t> at,
                                                    const ceres::Manifold* quaternion) {
  std::vector<const ceres::Manifold*> manifolds(blocks, nullptr);
  for (size_t i : at) manifolds[i] = quaternion;
  return manifolds;
}

TEST(ShiftedGnssResidual, JacobiansPassGradientChecker) {
  const geometry::RightQuaternionManifold quaternion;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    const FixedAxisMotion m = RandomMotion(&rng);
    FixedAxisMotion::State k = m.At(0.0);
    k.v += Eigen::Vector3d(u(rng), u(rng), u(rng));  // away from the truth: nonzero residuals
    Eigen::Vector3d p_I_A = Eigen::Vector3d(u(rng), u(rng), u(rng));
    double offset_s = 0.1 * u(rng);
    const std::vector<double*> blocks = {
        k.q.coeffs().data(), k.p.data(),   k.v.data(), k.b_g.data(),
        k.b_a.data(),        p_I_A.data(), &offset_s};
    for (const factors::GnssAxes axes :
         {factors::GnssAxes::kAll, factors::GnssAxes::kHorizontal, factors::GnssAxes::kVertical}) {
      std::unique_ptr<ceres::CostFunction> cost(ShiftedGnssResidual::Create(
          FixAt(m, p_I_A, 0.05), StampNs(0.04), StampNs(0.0), m.Imu(0.0), axes));
      EXPECT_EQ(cost->num_residuals(), factors::NumRows(axes));
      test::ExpectGradientCheckPasses(*cost, WithQuaternions(blocks.size(), {0}, &quaternion),
                                      blocks, 1e-6, "trial " + std::to_string(trial));
    }
  }
}

// Intrinsics: r_l, r_r, b (angular rates); s_l, s_r, b (linear speeds); k_v, b_eff, and
// b_ctrl (speed and yaw rate).
struct WheelIntrinsics {
  double left = 0.31, right = 0.34, track_m = 1.55;
  double k_v = 0.96, b_eff = 2.1, b_ctrl = 1.2;

  std::vector<double*> Blocks(const ShiftedWheelForm& form) {
    if (form.form == sensors::WheelForm::kSpeedYawRate) return {&k_v, &b_eff};
    if (form.shared_radius) return {&left, &track_m};
    return {&left, &right, &track_m};
  }
  // The form's two values for a rear-axle speed v and yaw rate w.
  Eigen::Vector2d Reported(const ShiftedWheelForm& form, double v, double w) const {
    if (form.form == sensors::WheelForm::kSpeedYawRate) {
      return Eigen::Vector2d(v / k_v, w * b_eff / (k_v * b_ctrl));
    }
    const double r = form.shared_radius ? left : right;
    return Eigen::Vector2d((v - 0.5 * w * track_m) / left, (v + 0.5 * w * track_m) / r);
  }
};

std::vector<ShiftedWheelForm> AllWheelForms() {
  ShiftedWheelForm rates, shared, speeds, odometry;
  shared.shared_radius = true;
  speeds.form = sensors::WheelForm::kLinearSpeeds;
  odometry.form = sensors::WheelForm::kSpeedYawRate;
  odometry.controller_track_m = WheelIntrinsics().b_ctrl;
  return {rates, shared, speeds, odometry};
}

std::string FormName(const ShiftedWheelForm& form) {
  return std::string(sensors::WheelFormName(form.form)) + (form.shared_radius ? " (shared)" : "");
}

// Two motions the rear axle can make that Eq. K16 carries exactly: speeding up along its own
// x axis without turning, and turning in place about its own up axis (a skid steer, V at the
// IMU) at a yaw rate that changes linearly.
struct VehicleCase {
  std::string name;
  FixedAxisMotion motion;
  Eigen::Quaterniond q_I_V;
  Eigen::Vector3d p_I_V;
  double accel_m_s2 = 0.0, yaw_accel_rad_s2 = 0.0;
  double Speed(double t) const { return (q_I_V.conjugate() * (Q(t).conjugate() * V(t))).x(); }
  double YawRate(double t) const { return (q_I_V.conjugate() * motion.Rate(t)).z(); }
  Eigen::Quaterniond Q(double t) const { return motion.Q(t); }
  Eigen::Vector3d V(double t) const { return motion.V(t); }
};

std::vector<VehicleCase> VehicleCases() {
  const Eigen::Quaterniond q_I_V(Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitX()) *
                                 Eigen::AngleAxisd(-0.2, Eigen::Vector3d::UnitZ()));
  const Eigen::Quaterniond q_W_V(Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()));
  VehicleCase straight{"speeding up", {}, q_I_V, Eigen::Vector3d(-1.2, 0.1, -0.4), 0.7, 0.0};
  straight.motion.q0 = q_W_V * q_I_V.conjugate();
  straight.motion.v0 = q_W_V * Eigen::Vector3d(4.0, 0.0, 0.0);
  straight.motion.a = q_W_V * Eigen::Vector3d(straight.accel_m_s2, 0.0, 0.0);
  VehicleCase turn{"turning in place", {}, q_I_V, Eigen::Vector3d::Zero(), 0.0, -0.15};
  turn.motion.q0 = straight.motion.q0;
  turn.motion.u = q_I_V * Eigen::Vector3d::UnitZ();
  turn.motion.w0 = 0.4;
  turn.motion.w1 = turn.yaw_accel_rad_s2;
  for (VehicleCase* c : {&straight, &turn}) {
    c->motion.b_g = Eigen::Vector3d(0.003, -0.002, 0.001);
    c->motion.b_a = Eigen::Vector3d(0.05, 0.02, -0.04);
  }
  return {straight, turn};
}

// Eq. F22 at the sample's IMU time: zero at the true offset; at offset 0 the speed row is off
// by the speed's change over the offset and the yaw-rate row by the yaw rate's, and the offset's
// Jacobian is the state's own rates (the acceleration and the gyro's slope).
TEST(ShiftedWheelResidual, VanishesAtTheTrueOffsetAndNotAtZeroForEveryForm) {
  const double offset_s = -0.2;  // the wheels stamp 0.2 s late
  factors::WheelFactorOptions options;
  for (const VehicleCase& c : VehicleCases()) {
    for (ShiftedWheelForm form : AllWheelForms()) {
      WheelIntrinsics intrinsics;
      if (form.shared_radius) intrinsics.right = intrinsics.left;
      const std::string at = c.name + ", " + FormName(form);
      const double t_k = 2.0, t_sample = t_k + 0.004 - offset_s;
      const double t_taken = t_sample + offset_s;
      FixedAxisMotion::State k = c.motion.At(t_k);
      Eigen::Quaterniond q_I_V = c.q_I_V;
      Eigen::Vector3d p_I_V = c.p_I_V;
      // Paired at the true offset: the rows' rate is the gyro where the sample was taken.
      const internal::PairedWheelSample sample{
          intrinsics.Reported(form, c.Speed(t_taken), c.YawRate(t_taken)), StampNs(t_sample),
          offset_s, c.motion.Rate(t_taken) + c.motion.b_g};
      std::unique_ptr<ceres::CostFunction> cost(
          ShiftedWheelResidual::Create(sample, StampNs(t_k), c.motion.Imu(t_k), form, options));
      std::vector<double*> blocks = {k.q.coeffs().data(),   k.v.data(),  k.b_g.data(), k.b_a.data(),
                                     q_I_V.coeffs().data(), p_I_V.data()};
      for (double* block : intrinsics.Blocks(form)) blocks.push_back(block);
      double offset = offset_s;
      blocks.push_back(&offset);
      Eigen::Vector4d r;
      ASSERT_TRUE(cost->Evaluate(blocks.data(), r.data(), nullptr)) << at;
      EXPECT_LT(r.norm(), 1e-6) << at;  // 1e-6 sigma: the stamps' rounding
      offset = 0.0;
      std::vector<double> jacobian_offset(4);
      std::vector<double*> jacobians(blocks.size(), nullptr);
      jacobians.back() = jacobian_offset.data();
      ASSERT_TRUE(cost->Evaluate(blocks.data(), r.data(), jacobians.data())) << at;
      EXPECT_NEAR(r(0), -c.accel_m_s2 * offset_s / options.speed_sigma_m_s, 1e-6) << at;
      EXPECT_NEAR(r(1), -c.yaw_accel_rad_s2 * offset_s / options.yaw_rate_sigma_rad_s, 1e-6) << at;
      EXPECT_NEAR(jacobian_offset[0], c.accel_m_s2 / options.speed_sigma_m_s, 1e-6) << at;
      EXPECT_NEAR(jacobian_offset[1], c.yaw_accel_rad_s2 / options.yaw_rate_sigma_rad_s, 1e-6)
          << at;
      // The non-holonomic rows hold the paired instant: the offset does not move them.
      EXPECT_EQ(jacobian_offset[2], 0.0) << at;
      EXPECT_EQ(jacobian_offset[3], 0.0) << at;
    }
  }
}

TEST(ShiftedWheelResidual, JacobiansPassGradientCheckerForEveryForm) {
  const geometry::RightQuaternionManifold quaternion;
  std::mt19937 rng(13);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  factors::WheelFactorOptions options;
  for (const ShiftedWheelForm& form : AllWheelForms()) {
    for (int trial = 0; trial < 10; ++trial) {
      const FixedAxisMotion m = RandomMotion(&rng);
      FixedAxisMotion::State k = m.At(0.0);
      Eigen::Quaterniond q_I_V = Eigen::Quaterniond::UnitRandom();
      Eigen::Vector3d p_I_V(u(rng), u(rng), u(rng));
      WheelIntrinsics intrinsics;
      double offset_s = 0.05 * u(rng);
      std::vector<double*> blocks = {k.q.coeffs().data(),   k.v.data(),  k.b_g.data(), k.b_a.data(),
                                     q_I_V.coeffs().data(), p_I_V.data()};
      for (double* block : intrinsics.Blocks(form)) blocks.push_back(block);
      blocks.push_back(&offset_s);
      const internal::PairedWheelSample sample{Eigen::Vector2d(10.0 + u(rng), 11.0 + u(rng)),
                                               StampNs(0.003), 0.05 * u(rng),
                                               m.Imu(0.0).gyro_rad_s + 0.1 * m.u};
      std::unique_ptr<ceres::CostFunction> cost(
          ShiftedWheelResidual::Create(sample, StampNs(0.0), m.Imu(0.0), form, options));
      test::ExpectGradientCheckPasses(*cost, WithQuaternions(blocks.size(), {0, 4}, &quaternion),
                                      blocks, 1e-6,
                                      FormName(form) + " trial " + std::to_string(trial));
    }
  }
}

// A log whose gyro and specific force change linearly in time, at 200 Hz.
sensors::ImuSamples LinearImu(double noise, std::mt19937* rng) {
  std::normal_distribution<double> n(0.0, noise);
  sensors::ImuSamples imu;
  for (int i = 0; i < 2000; ++i) {
    const double t = 0.005 * i;
    sensors::ImuSample s;
    s.t_ns = StampNs(t);
    s.gyro_rad_s = Eigen::Vector3d(0.1 + 0.02 * t, -0.3 * t, 0.05) +
                   Eigen::Vector3d(n(*rng), n(*rng), n(*rng));
    s.accel_m_s2 = Eigen::Vector3d(1.0 - 0.1 * t, 0.2, 9.8 + 0.01 * t);
    imu.push_back(s);
  }
  return imu;
}

TEST(ImuAround, ReadsTheRatesTheirSlopeAndTheSpecificForce) {
  std::mt19937 rng(17);
  const sensors::ImuSamples imu = LinearImu(0.0, &rng);
  const int64_t max_gap_ns = SecondsToNs(0.0125);
  for (const double t : {0.0, 0.0123, 5.0, 9.995}) {
    const ImuAroundKeyframe around = *ImuAround(imu, StampNs(t), kGravity, max_gap_ns);
    const std::string at = "t = " + std::to_string(t);
    EXPECT_LT((around.gyro_rad_s - Eigen::Vector3d(0.1 + 0.02 * t, -0.3 * t, 0.05)).norm(), 1e-9)
        << at;
    EXPECT_LT((around.gyro_slope_rad_s2 - Eigen::Vector3d(0.02, -0.3, 0.0)).norm(), 1e-9) << at;
    EXPECT_LT((around.accel_m_s2 - Eigen::Vector3d(1.0 - 0.1 * t, 0.2, 9.8 + 0.01 * t)).norm(),
              1e-9)
        << at;
    EXPECT_EQ(around.g_W, Eigen::Vector3d(0.0, 0.0, -kGravity));
  }
  // The line averages the samples' noise: the slope of a line through 41 samples 5 ms apart
  // is good to sigma / sqrt(sum (t_i - t_mean)^2) = 2.64 sigma per second, that of two samples
  // to 283 sigma.
  const double sigma = 0.01;
  const sensors::ImuSamples noisy = LinearImu(sigma, &rng);
  double sum_squares = 0.0;
  int n = 0;
  for (double t = 1.0; t < 9.0; t += 0.1, ++n) {
    const ImuAroundKeyframe around = *ImuAround(noisy, StampNs(t), kGravity, max_gap_ns);
    sum_squares += (around.gyro_slope_rad_s2 - Eigen::Vector3d(0.02, -0.3, 0.0)).squaredNorm();
  }
  const double rms = std::sqrt(sum_squares / (3.0 * n));
  EXPECT_LT(rms, 3.2 * sigma);
  EXPECT_GT(rms, 2.1 * sigma);

  // Outside the samples, or where an IMU dropout lies among those the lines take: none.
  EXPECT_FALSE(ImuAround(imu, StampNs(10.1), kGravity, max_gap_ns));
  sensors::ImuSamples dropout(imu.begin(), imu.begin() + 1000);  // to 4.995 s
  dropout.insert(dropout.end(), imu.begin() + 1020, imu.end());  // from 5.1 s
  EXPECT_FALSE(ImuAround(dropout, StampNs(5.0), kGravity, max_gap_ns));
  EXPECT_FALSE(ImuAround(dropout, StampNs(5.05), kGravity, max_gap_ns));
  EXPECT_TRUE(ImuAround(dropout, StampNs(5.15), kGravity, max_gap_ns));
  EXPECT_THROW(ImuAround(sensors::ImuSamples(imu.begin(), imu.begin() + 1), StampNs(0.0), kGravity,
                         max_gap_ns),
               Error);
}

std::vector<Keyframe> KeyframesAt(const std::vector<double>& t_s) {
  std::vector<Keyframe> keyframes(t_s.size());
  for (size_t k = 0; k < t_s.size(); ++k) keyframes[k].t_ns = StampNs(t_s[k]);
  return keyframes;
}

sensors::GnssFixes FixesAt(const std::vector<double>& t_s) {
  sensors::GnssFixes fixes(t_s.size());
  for (size_t j = 0; j < t_s.size(); ++j) fixes[j].t_ns = StampNs(t_s[j]);
  return fixes;
}

// Eq. K17: each keyframe takes the sample nearest t_k - offset within the distance, and no
// sample serves two keyframes.
TEST(NearestSamples, PairsEachKeyframeWithItsNearestSampleOnce) {
  using internal::NearestSamples;
  const int64_t offset_ns = SecondsToNs(-0.02);  // stamped 20 ms after they were taken
  // Samples stamped every 10 ms from 0 s, taken from -0.02 s to 0.97 s.
  std::vector<double> dense;
  for (int j = 0; j < 100; ++j) dense.push_back(0.01 * j);
  const auto paired = NearestSamples(FixesAt(dense), KeyframesAt({0.0, 0.1037, 0.5, 0.97, 0.99}),
                                     offset_ns, SecondsToNs(0.01));
  const std::vector<std::optional<size_t>> expected = {2, 12, 52, 99, std::nullopt};
  EXPECT_EQ(paired, expected);  // the last keyframe is 20 ms after the last sample was taken

  // Samples sparser than the keyframes: each serves the keyframe nearest it, the others get
  // none, however far the distance allows.
  const std::vector<Keyframe> keyframes =
      KeyframesAt({0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9});
  const auto sparse =
      NearestSamples(FixesAt({0.0, 0.29, 0.52, 0.81}), keyframes, offset_ns, SecondsToNs(1.0));
  const std::vector<std::optional<size_t>> each_once = {
      0, std::nullopt, std::nullopt, 1, std::nullopt,
      2, std::nullopt, std::nullopt, 3, std::nullopt};
  EXPECT_EQ(sparse, each_once);
  // Beyond the first and the last keyframe, no farther than half their interval (50 ms): the
  // fix taken 20 ms before the first is kept, the one taken 70 ms after the last is not.
  const auto ends = NearestSamples(FixesAt({0.0, 0.99}), KeyframesAt({0.0, 0.1, 0.8, 0.9}),
                                   offset_ns, SecondsToNs(1.0));
  EXPECT_EQ(ends,
            (std::vector<std::optional<size_t>>{0, std::nullopt, std::nullopt, std::nullopt}));
  // Equally far from two keyframes, a sample serves the earlier one.
  const auto tie =
      NearestSamples(FixesAt({0.07}), KeyframesAt({0.0, 0.1}), offset_ns, SecondsToNs(1.0));
  EXPECT_EQ(tie, (std::vector<std::optional<size_t>>{0, std::nullopt}));
  // Samples half a period off keyframes as dense as they are (a receiver and a LiDAR both on
  // the second, 50 ms apart): each keyframe takes the later of its two samples, which serves
  // no other, so every keyframe has one. (Taking the earlier, each lost it to the keyframe
  // before, and none had a sample.)
  const auto half_period =
      NearestSamples(FixesAt({0.0, 0.1, 0.2, 0.3, 0.4}), KeyframesAt({0.03, 0.13, 0.23, 0.33}),
                     offset_ns, SecondsToNs(0.05));
  EXPECT_EQ(half_period, (std::vector<std::optional<size_t>>{1, 2, 3, 4}));
}

// Fixes without a clock that keyframes would share: each serves the keyframe nearest it, so a
// keyframe may take several and every fix counts once.
TEST(NearestKeyframes, GivesEachSampleItsNearestKeyframe) {
  using internal::NearestKeyframes;
  using Served = std::vector<std::optional<size_t>>;
  const std::vector<Keyframe> keyframes = KeyframesAt({0.0, 0.2, 0.4, 0.6});
  // 8 Hz against 5 Hz: the keyframe at 0.2 s takes two fixes.
  EXPECT_EQ(NearestKeyframes(FixesAt({0.0, 0.125, 0.25, 0.375}), keyframes, SecondsToNs(1.0)),
            (Served{0, 1, 1, 2}));
  // Midway between two keyframes, a fix serves the later; so fixes half a period off the
  // keyframes all count.
  EXPECT_EQ(NearestKeyframes(FixesAt({0.1, 0.3, 0.5}), keyframes, SecondsToNs(1.0)),
            (Served{1, 2, 3}));
  // Beyond the first and the last keyframe no farther than half their interval (0.1 s), and
  // none beyond the distance.
  EXPECT_EQ(NearestKeyframes(FixesAt({-0.1, -0.05, 0.65, 0.7}), keyframes, SecondsToNs(1.0)),
            (Served{0, 0, 3, std::nullopt}));
  EXPECT_EQ(NearestKeyframes(FixesAt({0.05, 0.13}), keyframes, SecondsToNs(0.06)),
            (Served{0, std::nullopt}));
}

}  // namespace
}  // namespace estimation
}  // namespace autocal
