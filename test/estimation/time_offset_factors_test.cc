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
    std::unique_ptr<ceres::CostFunction> cost(ShiftedGnssResidual::Create(series, t_ns));
    const std::vector<double*> blocks = {q.coeffs().data(), p.data(), p_I_A.data(), &offset_s};
    test::ExpectGradientCheckPasses(*cost, manifolds, blocks, 1e-6,
                                    "trial " + std::to_string(trial));
  }
}

}  // namespace
}  // namespace estimation
}  // namespace autocal
