#include "autocal/estimation/dead_reckoning_keyframes.h"

#include <ceres/ceres.h>
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "autocal/common/error.h"
#include "autocal/common/time.h"
#include "autocal/geometry/manifolds.h"
#include "autocal/geometry/so3.h"

namespace autocal {
namespace estimation {
namespace {

// A platform on a circle: speed v along its x axis, yaw rate w, the IMU mounted at q_I_V.
struct Circle {
  double v_m_s = 2.0;
  double w_rad_s = 0.2;
  Eigen::Quaterniond q_I_V =
      Eigen::Quaterniond(Eigen::AngleAxisd(-M_PI / 2, Eigen::Vector3d::UnitZ()) *
                         Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitX()));
};

std::vector<Keyframe> Keyframes(double period_s, double duration_s) {
  std::vector<Keyframe> kfs;
  for (double t = 0.5; t <= duration_s; t += period_s) {
    Keyframe kf;
    kf.t_ns = SecondsToNs(t);
    kfs.push_back(kf);
  }
  return kfs;
}

// The IMU of the circle at 200 Hz for 11 s (its centripetal force and gravity) and the wheel
// speed at 10 Hz.
sensors::ImuSamples ImuOnCircle(const Circle& c) {
  sensors::ImuSamples imu;
  for (double t = 0.0; t <= 11.0; t += 0.005) {
    sensors::ImuSample s;
    s.t_ns = SecondsToNs(t);
    s.gyro_rad_s = c.q_I_V * Eigen::Vector3d(0.0, 0.0, c.w_rad_s);
    s.accel_m_s2 = c.q_I_V * Eigen::Vector3d(0.0, c.v_m_s * c.w_rad_s, 9.80665);
    imu.push_back(s);
  }
  return imu;
}

ScalarSeries SpeedOnCircle(const Circle& c) {
  ScalarSeries speed;
  for (double t = 0.0; t <= 11.0; t += 0.1) speed.push_back({SecondsToNs(t), c.v_m_s});
  return speed;
}

// (K12) on the circle: each keyframe's yaw is w t from the first, its velocity the speed along
// its heading, its position on the arc (the trapezoid rule's error is below a millimetre).
TEST(PlaceKeyframesByDeadReckoning, FollowsACircle) {
  const Circle c;
  const sensors::ImuSamples imu = ImuOnCircle(c);
  const ScalarSeries speed = SpeedOnCircle(c);
  std::vector<Keyframe> kfs = Keyframes(0.1, 10.0);
  PlaceKeyframesByDeadReckoning(&kfs, imu, speed, c.q_I_V, Eigen::Vector3d::Zero());
  const double t0 = NsToSeconds(kfs.front().t_ns);
  const double radius_m = c.v_m_s / c.w_rad_s;
  for (const Keyframe& kf : kfs) {
    const double psi = c.w_rad_s * (NsToSeconds(kf.t_ns) - t0);
    const Eigen::Quaterniond q_W_V(Eigen::AngleAxisd(psi, Eigen::Vector3d::UnitZ()));
    EXPECT_LT(geometry::AngularDistance(kf.q_W_I, q_W_V * c.q_I_V.conjugate()), 1e-6);
    EXPECT_LT((kf.v_W_I - q_W_V * Eigen::Vector3d(c.v_m_s, 0.0, 0.0)).norm(), 1e-9);
    const Eigen::Vector3d on_arc(radius_m * std::sin(psi), radius_m * (1.0 - std::cos(psi)), 0.0);
    EXPECT_LT((kf.p_W_I - on_arc).norm(), 1e-3);
    EXPECT_EQ(kf.b_g, Eigen::Vector3d::Zero());
  }
  EXPECT_THROW(
      PlaceKeyframesByDeadReckoning(&kfs, imu, ScalarSeries(), c.q_I_V, Eigen::Vector3d::Zero()),
      Error);
  std::vector<Keyframe> late = Keyframes(0.1, 20.0);
  EXPECT_THROW(PlaceKeyframesByDeadReckoning(&late, imu, speed, c.q_I_V, Eigen::Vector3d::Zero()),
               Error);
}

// With the IMU away from the rear axle (p_I_V), it moves with the axle plus the turn about it:
// v_W_I = v_W_V + w x p_V_I, the gyro's w constant on the circle.
TEST(PlaceKeyframesByDeadReckoning, AddsTheTurnAboutTheRearAxle) {
  const Circle c;
  const sensors::ImuSamples imu = ImuOnCircle(c);
  const ScalarSeries speed = SpeedOnCircle(c);
  const Eigen::Vector3d p_I_V(0.4, -1.3, 0.2);
  std::vector<Keyframe> kfs = Keyframes(0.1, 10.0);
  PlaceKeyframesByDeadReckoning(&kfs, imu, speed, c.q_I_V, p_I_V);
  const Eigen::Vector3d p_V_I = -(c.q_I_V.conjugate() * p_I_V);  // the IMU in V
  const Eigen::Vector3d w_V(0.0, 0.0, c.w_rad_s);
  const double t0 = NsToSeconds(kfs.front().t_ns);
  for (const Keyframe& kf : kfs) {
    const double psi = c.w_rad_s * (NsToSeconds(kf.t_ns) - t0);
    const Eigen::Quaterniond q_W_V(Eigen::AngleAxisd(psi, Eigen::Vector3d::UnitZ()));
    const Eigen::Vector3d expected =
        q_W_V * (Eigen::Vector3d(c.v_m_s, 0.0, 0.0) + w_V.cross(p_V_I));
    EXPECT_LT((kf.v_W_I - expected).norm(), 1e-9);
  }
}

// The gauge holds the first keyframe's position and its turn about the world's vertical, and
// nothing else: its roll and pitch stay free for gravity to set.
TEST(AddDeadReckoningGauge, HoldsPositionAndYawOnly) {
  Keyframe kf;
  kf.q_W_I = Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()));
  kf.p_W_I = Eigen::Vector3d(1.0, -2.0, 0.5);
  geometry::RightQuaternionManifold manifold;
  ceres::Problem::Options options;
  options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(options);
  problem.AddParameterBlock(kf.q_W_I.coeffs().data(), 4, &manifold);
  problem.AddParameterBlock(kf.p_W_I.data(), 3);
  AddDeadReckoningGauge(&problem, &kf, 1e-3, 1e-4);
  const auto cost = [&] {
    double c = 0.0;
    problem.Evaluate(ceres::Problem::EvaluateOptions(), &c, nullptr, nullptr, nullptr);
    return c;
  };
  EXPECT_NEAR(cost(), 0.0, 1e-12);
  const Keyframe start = kf;
  // A turn about the world's x axis (a roll of the platform) costs nothing.
  kf.q_W_I = Eigen::Quaterniond(Eigen::AngleAxisd(0.05, Eigen::Vector3d::UnitX())) * start.q_W_I;
  EXPECT_NEAR(cost(), 0.0, 1e-9);
  // A turn about the vertical costs (0.01 / 1e-4)^2 / 2.
  kf.q_W_I = Eigen::Quaterniond(Eigen::AngleAxisd(0.01, Eigen::Vector3d::UnitZ())) * start.q_W_I;
  EXPECT_NEAR(cost(), 0.5 * 1e4, 1.0);
  kf.q_W_I = start.q_W_I;
  kf.p_W_I.z() += 1e-3;  // one sigma
  EXPECT_NEAR(cost(), 0.5, 1e-9);
  EXPECT_THROW(AddDeadReckoningGauge(&problem, &kf, 0.0, 1e-4), Error);
}

}  // namespace
}  // namespace estimation
}  // namespace autocal
