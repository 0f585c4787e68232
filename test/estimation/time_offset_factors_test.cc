#include "estimation/time_offset_factors.h"

#include <ceres/ceres.h>
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "autocal/geometry/manifolds.h"
#include "factors/factor_test_utils.h"

namespace autocal {
namespace estimation {
namespace {

using internal::GnssSeries;
using internal::ShiftedGnssResidual;
using internal::ShiftedWheelForm;
using internal::ShiftedWheelResidual;
using internal::WheelSeries;

constexpr int64_t kStartNs = 1'700'000'000'000'000'000;

// The antenna moves at a constant velocity (so linear interpolation of the fixes is exact)
// and the receiver stamps each fix with its own clock: a fix stamped t_s holds the antenna at
// IMU time t_s + offset_s. Fixes at 2.5 Hz with 3 ms stamp jitter.
struct ConstantVelocityAntenna {
  Eigen::Vector3d p0_m{10.0, -4.0, 2.0};
  Eigen::Vector3d v_m_s{0.9, 0.3, -0.05};
  Eigen::Vector3d At(double t_imu_s) const { return p0_m + v_m_s * t_imu_s; }

  std::shared_ptr<const GnssSeries> Fixes(double offset_s) const {
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> jitter_s(-0.003, 0.003);
    std::vector<int64_t> t_ns;
    std::vector<GnssSeries::Value> rows;
    for (int i = 0; i < 40; ++i) {
      const double t_s = 0.4 * i + jitter_s(rng);
      t_ns.push_back(kStartNs + static_cast<int64_t>(std::llround(t_s * 1e9)));
      GnssSeries::Value row;
      row << At(t_s + offset_s), 0.8, 0.9, 1.5;
      rows.push_back(row);
    }
    return std::make_shared<const GnssSeries>(t_ns, rows, "GNSS");
  }
};

TEST(ShiftedGnssResidual, VanishesAtTheTrueOffsetAndNotAtZero) {
  const ConstantVelocityAntenna antenna;
  const double offset_s = -0.21;  // the receiver stamps 0.21 s after the fix
  const auto series = antenna.Fixes(offset_s);
  for (int k = 0; k < 10; ++k) {
    const double t_k_s = 2.0 + 1.3 * k;
    const Eigen::Quaterniond q_W_I = Eigen::Quaterniond::UnitRandom();
    const Eigen::Vector3d p_I_A(0.3, -0.1, 0.7);
    const Eigen::Vector3d p_W_I = antenna.At(t_k_s) - q_W_I * p_I_A;
    const int64_t t_ns = kStartNs + static_cast<int64_t>(std::llround(t_k_s * 1e9));
    const ShiftedGnssResidual at_k(series, t_ns);
    Eigen::Vector3d r;
    ASSERT_TRUE(at_k(q_W_I.coeffs().data(), p_W_I.data(), p_I_A.data(), &offset_s, r.data()));
    EXPECT_LT(r.norm(), 1e-9) << "t_k = " << t_k_s;
    // Ignoring the offset reads the fix stamped t_k, the antenna at t_k + offset: 0.2 m off.
    const double zero = 0.0;
    ASSERT_TRUE(at_k(q_W_I.coeffs().data(), p_W_I.data(), p_I_A.data(), &zero, r.data()));
    EXPECT_NEAR(r.x(), -antenna.v_m_s.x() * offset_s / 0.8, 1e-8);
  }
}

TEST(ShiftedGnssResidual, JacobiansPassGradientChecker) {
  const ConstantVelocityAntenna antenna;
  const auto series = antenna.Fixes(0.15);
  const geometry::RightQuaternionManifold quaternion;
  const std::vector<const ceres::Manifold*> manifolds = {&quaternion, nullptr, nullptr, nullptr};
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    Eigen::Quaterniond q = Eigen::Quaterniond::UnitRandom();
    Eigen::Vector3d p = Eigen::Vector3d(u(rng), u(rng), u(rng)) * 30.0;
    Eigen::Vector3d p_I_A = Eigen::Vector3d(u(rng), u(rng), u(rng));
    // Keyframe and offset chosen so the shifted instant is inside a segment (the series is
    // piecewise linear in the offset; the checker's steps stay within 0.005 s).
    const int64_t t_ns = kStartNs + int64_t{2'200'000'000} + int64_t{400'000'000} * trial;
    double offset_s = 0.4 + 0.03 * u(rng);
    const std::vector<double*> blocks = {q.coeffs().data(), p.data(), p_I_A.data(), &offset_s};
    for (const factors::GnssAxes axes :
         {factors::GnssAxes::kAll, factors::GnssAxes::kHorizontal, factors::GnssAxes::kVertical}) {
      std::unique_ptr<ceres::CostFunction> cost(ShiftedGnssResidual::Create(series, t_ns, axes));
      EXPECT_EQ(cost->num_residuals(), factors::NumRows(axes));
      test::ExpectGradientCheckPasses(*cost, manifolds, blocks, 1e-6,
                                      "trial " + std::to_string(trial));
    }
  }
}

// A vehicle whose rear-axle speed and yaw rate change linearly in IMU time (so linear
// interpolation of the wheel samples is exact), seen by wheels stamped on their own clock:
// a sample stamped t_s holds the motion at IMU time t_s + offset_s. 10 Hz with 2 ms jitter.
struct LinearDrive {
  double speed_m_s = 4.0, accel_m_s2 = 0.7;
  double yaw_rate_rad_s = 0.2, yaw_accel_rad_s2 = -0.15;
  // Intrinsics: r_l, r_r, b (angular rates); s_l, s_r, b (linear speeds); k_v, b_eff, and
  // b_ctrl (speed and yaw rate).
  double left = 0.31, right = 0.34, track_m = 1.55;
  double k_v = 0.96, b_eff = 2.1, b_ctrl = 1.2;

  double Speed(double t_s) const { return speed_m_s + accel_m_s2 * t_s; }
  double YawRate(double t_s) const { return yaw_rate_rad_s + yaw_accel_rad_s2 * t_s; }

  std::vector<double*> Intrinsics(const ShiftedWheelForm& form) {
    if (form.form == sensors::WheelForm::kSpeedYawRate) return {&k_v, &b_eff};
    if (form.shared_radius) return {&left, &track_m};
    return {&left, &right, &track_m};
  }

  WheelSeries::Value Reported(const ShiftedWheelForm& form, double t_imu_s) const {
    const double v = Speed(t_imu_s), w = YawRate(t_imu_s);
    if (form.form == sensors::WheelForm::kSpeedYawRate) {
      return WheelSeries::Value(v / k_v, w * b_eff / (k_v * b_ctrl));
    }
    const double r = form.shared_radius ? left : right;
    return WheelSeries::Value((v - 0.5 * w * track_m) / left, (v + 0.5 * w * track_m) / r);
  }

  std::shared_ptr<const WheelSeries> Samples(const ShiftedWheelForm& form, double offset_s) const {
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> jitter_s(-0.002, 0.002);
    std::vector<int64_t> t_ns;
    std::vector<WheelSeries::Value> rows;
    for (int i = 0; i < 200; ++i) {
      const double t_s = 0.1 * i + jitter_s(rng);
      t_ns.push_back(kStartNs + static_cast<int64_t>(std::llround(t_s * 1e9)));
      rows.push_back(Reported(form, t_s + offset_s));
    }
    return std::make_shared<const WheelSeries>(t_ns, rows, "wheel");
  }
};

// A keyframe state that moves the rear axle at (speed, 0, 0) and turns it at yaw_rate about
// its up axis, and the raw gyro that goes with it.
struct WheelState {
  Eigen::Quaterniond q_W_I, q_I_V;
  Eigen::Vector3d v_W_I, b_g, p_I_V, gyro;

  WheelState(double speed, double yaw_rate, std::mt19937* rng) {
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    q_W_I = Eigen::Quaterniond::UnitRandom();
    q_I_V = Eigen::Quaterniond(Eigen::AngleAxisd(0.2 * u(*rng), Eigen::Vector3d::UnitX()) *
                               Eigen::AngleAxisd(0.3 * u(*rng), Eigen::Vector3d::UnitZ()));
    p_I_V = Eigen::Vector3d(u(*rng), u(*rng), u(*rng));
    b_g = 0.01 * Eigen::Vector3d(u(*rng), u(*rng), u(*rng));
    const Eigen::Vector3d w_I = q_I_V * Eigen::Vector3d(0.0, 0.0, yaw_rate);
    gyro = w_I + b_g;
    v_W_I = q_W_I * (q_I_V * Eigen::Vector3d(speed, 0.0, 0.0) - w_I.cross(p_I_V));
  }
  std::vector<double*> Blocks() {
    return {q_W_I.coeffs().data(), v_W_I.data(), b_g.data(), q_I_V.coeffs().data(), p_I_V.data()};
  }
};

std::vector<ShiftedWheelForm> AllWheelForms() {
  ShiftedWheelForm rates, shared, speeds, odometry;
  shared.shared_radius = true;
  speeds.form = sensors::WheelForm::kLinearSpeeds;
  odometry.form = sensors::WheelForm::kSpeedYawRate;
  odometry.controller_track_m = LinearDrive().b_ctrl;
  return {rates, shared, speeds, odometry};
}

std::string FormName(const ShiftedWheelForm& form) {
  return std::string(sensors::WheelFormName(form.form)) + (form.shared_radius ? " (shared)" : "");
}

TEST(ShiftedWheelResidual, VanishesAtTheTrueOffsetAndNotAtZeroForEveryForm) {
  LinearDrive drive;
  const double offset_s = -0.2;  // the wheels stamp 0.2 s late
  std::mt19937 rng(11);
  factors::WheelFactorOptions options;
  for (ShiftedWheelForm form : AllWheelForms()) {
    if (form.shared_radius) drive.right = drive.left;
    const auto series = drive.Samples(form, offset_s);
    for (int k = 0; k < 8; ++k) {
      const double t_k_s = 2.0 + 1.7 * k;
      WheelState state(drive.Speed(t_k_s), drive.YawRate(t_k_s), &rng);
      const int64_t t_ns = kStartNs + static_cast<int64_t>(std::llround(t_k_s * 1e9));
      std::unique_ptr<ceres::CostFunction> cost(
          ShiftedWheelResidual::Create(series, t_ns, state.gyro, form, options));
      std::vector<double*> blocks = state.Blocks();
      for (double* block : drive.Intrinsics(form)) blocks.push_back(block);
      double offset = offset_s;
      blocks.push_back(&offset);
      Eigen::Vector4d r;
      ASSERT_TRUE(cost->Evaluate(blocks.data(), r.data(), nullptr)) << FormName(form);
      // Whitened rows: 1e-7 is 1e-9 m/s on the speed, rounding of the epoch-sized stamps.
      EXPECT_LT(r.norm(), 1e-7) << FormName(form) << " t_k = " << t_k_s;
      // Read at t_k instead, the speed is the one 0.2 s earlier: 0.14 m/s, 7 sigma off.
      offset = 0.0;
      ASSERT_TRUE(cost->Evaluate(blocks.data(), r.data(), nullptr)) << FormName(form);
      EXPECT_NEAR(r(0), -drive.accel_m_s2 * offset_s / options.speed_sigma_m_s, 1e-6)
          << FormName(form);
    }
  }
}

TEST(ShiftedWheelResidual, JacobiansPassGradientCheckerForEveryForm) {
  LinearDrive drive;
  const geometry::RightQuaternionManifold quaternion;
  std::mt19937 rng(13);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  factors::WheelFactorOptions options;
  for (ShiftedWheelForm form : AllWheelForms()) {
    const auto series = drive.Samples(form, 0.35);
    for (int trial = 0; trial < 10; ++trial) {
      WheelState state(3.0 + u(rng), 0.3 * u(rng), &rng);
      state.v_W_I += 0.2 * Eigen::Vector3d(u(rng), u(rng), u(rng));  // nonzero residuals
      // The shifted instant inside a 0.1 s segment (the checker's steps are far smaller).
      const int64_t t_ns = kStartNs + int64_t{3'050'000'000} + int64_t{1'000'000'000} * trial;
      double offset_s = 0.4 + 0.02 * u(rng);
      std::vector<double*> blocks = state.Blocks();
      for (double* block : drive.Intrinsics(form)) blocks.push_back(block);
      blocks.push_back(&offset_s);
      std::vector<const ceres::Manifold*> manifolds(blocks.size(), nullptr);
      manifolds[0] = manifolds[3] = &quaternion;
      std::unique_ptr<ceres::CostFunction> cost(
          ShiftedWheelResidual::Create(series, t_ns, state.gyro, form, options));
      test::ExpectGradientCheckPasses(*cost, manifolds, blocks, 1e-6,
                                      FormName(form) + " trial " + std::to_string(trial));
    }
  }
}

// The offset's Jacobian is the segment's slope (Eq. K9): the speed row moves by
// -accel * d(offset) / sigma for a drive whose speed changes at accel.
TEST(ShiftedWheelResidual, OffsetJacobianIsTheSlope) {
  const LinearDrive drive;
  const ShiftedWheelForm form = AllWheelForms()[0];
  const auto series = drive.Samples(form, 0.0);
  std::mt19937 rng(17);
  WheelState state(drive.Speed(5.05), drive.YawRate(5.05), &rng);
  factors::WheelFactorOptions options;
  options.non_holonomic = false;
  const int64_t t_ns = kStartNs + int64_t{5'050'000'000};
  std::unique_ptr<ceres::CostFunction> cost(
      ShiftedWheelResidual::Create(series, t_ns, state.gyro, form, options));
  LinearDrive values = drive;
  std::vector<double*> blocks = state.Blocks();
  for (double* block : values.Intrinsics(form)) blocks.push_back(block);
  double offset_s = 0.0;
  blocks.push_back(&offset_s);
  std::vector<double> jacobian_offset(2);
  std::vector<double*> jacobians(blocks.size(), nullptr);
  jacobians.back() = jacobian_offset.data();
  Eigen::Vector2d r;
  ASSERT_TRUE(cost->Evaluate(blocks.data(), r.data(), jacobians.data()));
  // r0 = (v_state - v_wheel(t_k - offset)) / sigma: d r0 / d offset = +accel / sigma.
  EXPECT_NEAR(jacobian_offset[0], drive.accel_m_s2 / options.speed_sigma_m_s, 1e-6);
  EXPECT_NEAR(jacobian_offset[1], drive.yaw_accel_rad_s2 / options.yaw_rate_sigma_rad_s, 1e-6);
}

}  // namespace
}  // namespace estimation
}  // namespace autocal
