#include "autocal/estimation/planar_rotation_rows.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <random>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/geometry/manifolds.h"

namespace autocal {
namespace estimation {
namespace {

// Body rates of a robot turning back and forth (yaw rate up to 0.5 rad/s) with white roll and
// pitch rates of the given sigmas, seen through a mount tilted by `tilt` (about V's x and y).
std::vector<Eigen::Vector3d> TurningRates(const Eigen::Vector2d& sigma, const Eigen::Vector2d& tilt,
                                          double ar1, int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> unit(0.0, 1.0);
  const Eigen::Matrix3d R = (Eigen::AngleAxisd(tilt.x(), Eigen::Vector3d::UnitX()) *
                             Eigen::AngleAxisd(tilt.y(), Eigen::Vector3d::UnitY()))
                                .toRotationMatrix();
  std::vector<Eigen::Vector3d> rates;
  Eigen::Vector2d e = Eigen::Vector2d::Zero();
  const double innovation = std::sqrt(1.0 - ar1 * ar1);
  for (int k = 0; k < n; ++k) {
    e = ar1 * e + innovation * Eigen::Vector2d(unit(rng), unit(rng));
    const double yaw_rate = 0.5 * std::sin(0.05 * k);
    rates.push_back(R * Eigen::Vector3d(sigma.x() * e.x(), sigma.y() * e.y(), yaw_rate));
  }
  return rates;
}

TEST(PlanarRotationSpread, MeasuresTheRollAndPitchRatesAndTheTiltTheyShow) {
  const Eigen::Vector2d sigma(0.01, 0.03), tilt(0.02, -0.03);
  const PlanarRotationSpread s =
      MeasurePlanarRotationSpread(TurningRates(sigma, tilt, 0.0, 4000, 1));
  EXPECT_EQ(s.samples, 4000);
  for (int axis = 0; axis < 2; ++axis) {
    EXPECT_NEAR(s.sigma_rad_s(axis), sigma(axis), 0.06 * sigma(axis)) << axis;
    EXPECT_NEAR(s.correlation_scale(axis), 1.0, 0.1) << axis;
  }
  // A tilt d about x shows the yaw rate w in the y rate as -d w, about y in the x rate as d w.
  EXPECT_NEAR(s.slope.x(), tilt.y(), 2e-3);
  EXPECT_NEAR(s.slope.y(), -tilt.x(), 2e-3);
  // One sigma for both rows, the RMS of the two axes' (Eq. F27b).
  EXPECT_DOUBLE_EQ(s.RowSigmaRadS(),
                   std::sqrt(0.5 * s.sigma_rad_s.cwiseProduct(s.correlation_scale).squaredNorm()));
}

// An AR(1) series with coefficient a carries the information of n (1 - a) / (1 + a) white
// samples about its mean: the scale is sqrt((1 + a) / (1 - a)), 3 for a = 0.8.
TEST(PlanarRotationSpread, ScalesCorrelatedRatesByTheirIndependentSamples) {
  const PlanarRotationSpread s = MeasurePlanarRotationSpread(
      TurningRates(Eigen::Vector2d(0.02, 0.02), Eigen::Vector2d::Zero(), 0.8, 20000, 2));
  for (int axis = 0; axis < 2; ++axis) {
    EXPECT_NEAR(s.correlation_scale(axis), 3.0, 0.3) << axis;
    EXPECT_NEAR(s.sigma_rad_s(axis), 0.02, 0.002) << axis;
  }
}

TEST(PlanarRotationSpread, RefusesTooFewOrNonFiniteRates) {
  EXPECT_THROW(
      MeasurePlanarRotationSpread(std::vector<Eigen::Vector3d>(9, Eigen::Vector3d::Zero())), Error);
  std::vector<Eigen::Vector3d> rates =
      TurningRates(Eigen::Vector2d(0.01, 0.01), Eigen::Vector2d::Zero(), 0.0, 20, 3);
  rates[5].x() = std::nan("");
  EXPECT_THROW(MeasurePlanarRotationSpread(rates), Error);
}

// The rows on a mount whose tilt is the only unknown: the solve finds the tilt from the turns.
TEST(AddPlanarRotationFactors, FindTheMountTiltFromTheTurns) {
  const Eigen::Quaterniond q_true =
      Eigen::Quaterniond(Eigen::AngleAxisd(0.03, Eigen::Vector3d(1.0, -2.0, 0.5).normalized()));
  const Eigen::Vector2d sigma(0.01, 0.01);
  const std::vector<Eigen::Vector3d> rates_V =
      TurningRates(sigma, Eigen::Vector2d::Zero(), 0.0, 3000, 4);
  sensors::ImuSamples imu;
  std::vector<Keyframe> keyframes(rates_V.size());
  for (size_t k = 0; k < rates_V.size(); ++k) {
    sensors::ImuSample sample;
    sample.t_ns = static_cast<int64_t>(k) * 100'000'000;
    sample.gyro_rad_s = q_true * rates_V[k];
    sample.accel_m_s2 = Eigen::Vector3d(0.0, 0.0, 9.8);
    imu.push_back(sample);
    keyframes[k].t_ns = sample.t_ns;
  }
  sensors::Calibration calibration;
  calibration.q_I_V = Eigen::Quaterniond::Identity();
  ceres::Problem problem;
  problem.AddParameterBlock(calibration.q_I_V.coeffs().data(), 4,
                            new geometry::RightQuaternionManifold);
  PlanarRotationOptions rows_options;
  rows_options.loss = factors::LossOptions();
  const PlanarRotationRows rows =
      AddPlanarRotationFactors(&problem, imu, &keyframes, &calibration, rows_options);
  EXPECT_EQ(rows.added, static_cast<int>(keyframes.size()));
  for (Keyframe& kf : keyframes) problem.SetParameterBlockConstant(kf.b_g.data());
  ceres::Solver::Options solver;
  ceres::Solver::Summary summary;
  ceres::Solve(solver, &problem, &summary);
  // The turning axis: the mount's z axis in I matches the truth's to the rates' noise.
  const double angle = std::acos(std::min(
      1.0, (calibration.q_I_V * Eigen::Vector3d::UnitZ()).dot(q_true * Eigen::Vector3d::UnitZ())));
  EXPECT_LT(angle, 1e-3) << summary.BriefReport();
  EXPECT_THROW(AddPlanarRotationFactors(&problem, imu, &keyframes, &calibration,
                                        PlanarRotationOptions{-1.0}),
               Error);
}

}  // namespace
}  // namespace estimation
}  // namespace autocal
