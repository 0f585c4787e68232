// geometry::RollPitchYaw: ZYX angles with one representative per rotation, the form the
// report and the summary show mounts in.

#include "autocal/geometry/roll_pitch_yaw.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "autocal/common/units.h"
#include "autocal/geometry/so3.h"

namespace autocal {
namespace geometry {
namespace {

double AngleBetween(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  return AngularDistance(a, b);
}

TEST(RollPitchYaw, InvertsFromRollPitchYawInsideTheRanges) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> half_turn(-M_PI + 1e-6, M_PI);
  std::uniform_real_distribution<double> quarter_turn(-M_PI / 2 + 1e-3, M_PI / 2 - 1e-3);
  for (int i = 0; i < 1000; ++i) {
    const Eigen::Vector3d rpy(half_turn(rng), quarter_turn(rng), half_turn(rng));
    const Eigen::Vector3d back = RollPitchYaw(FromRollPitchYaw(rpy.x(), rpy.y(), rpy.z()));
    EXPECT_LT((back - rpy).cwiseAbs().maxCoeff(), 1e-9)
        << rpy.transpose() << " -> " << back.transpose();
  }
}

TEST(RollPitchYaw, NamesTheYUpMountOfTheSkidSteerLog) {
  // R_V_I = Rz(-90 deg) Rx(+90 deg): the IMU rolled 90 deg, then turned -90 deg about up.
  const Eigen::Quaterniond R_V_I(Eigen::AngleAxisd(-90 * kDegToRad, Eigen::Vector3d::UnitZ()) *
                                 Eigen::AngleAxisd(90 * kDegToRad, Eigen::Vector3d::UnitX()));
  const Eigen::Vector3d rpy = RollPitchYaw(R_V_I) * kRadToDeg;
  EXPECT_NEAR(rpy.x(), 90.0, 1e-9);
  EXPECT_NEAR(rpy.y(), 0.0, 1e-9);
  EXPECT_NEAR(rpy.z(), -90.0, 1e-9);
}

TEST(RollPitchYaw, AHalfTurnIsPlusPiWhicheverWayItWasBuilt) {
  for (const double yaw : {M_PI, -M_PI}) {
    const Eigen::Vector3d rpy = RollPitchYaw(FromRollPitchYaw(0.0, 0.0, yaw));
    EXPECT_NEAR(rpy.z(), M_PI, 1e-12);
    EXPECT_GT(rpy.z(), 0.0);
  }
  for (const double roll : {M_PI, -M_PI}) {
    const Eigen::Vector3d rpy = RollPitchYaw(FromRollPitchYaw(roll, 0.1, 0.2));
    EXPECT_NEAR(rpy.x(), M_PI, 1e-12);
    EXPECT_GT(rpy.x(), 0.0);
  }
  // q and -q are one rotation.
  const Eigen::Quaterniond q = FromRollPitchYaw(0.3, -0.4, 2.9);
  EXPECT_LT((RollPitchYaw(q) - RollPitchYaw(Eigen::Quaterniond(-q.coeffs()))).norm(), 1e-12);
}

TEST(RollPitchYaw, AtGimbalLockRollIsZeroAndYawCarriesTheTurn) {
  // Pitch +90 deg: only yaw - roll is determined.
  const Eigen::Quaterniond up = FromRollPitchYaw(0.3, M_PI / 2, 0.5);
  const Eigen::Vector3d a = RollPitchYaw(up);
  EXPECT_EQ(a.x(), 0.0);
  EXPECT_NEAR(a.y(), M_PI / 2, 1e-9);
  EXPECT_NEAR(a.z(), 0.2, 1e-9);
  EXPECT_LT(AngleBetween(FromRollPitchYaw(a.x(), a.y(), a.z()), up), 1e-9);
  // Pitch -90 deg: only yaw + roll is determined.
  const Eigen::Quaterniond down = FromRollPitchYaw(0.3, -M_PI / 2, 0.5);
  const Eigen::Vector3d b = RollPitchYaw(down);
  EXPECT_EQ(b.x(), 0.0);
  EXPECT_NEAR(b.y(), -M_PI / 2, 1e-9);
  EXPECT_NEAR(b.z(), 0.8, 1e-9);
  EXPECT_LT(AngleBetween(FromRollPitchYaw(b.x(), b.y(), b.z()), down), 1e-9);
}

TEST(RollPitchYaw, NearGimbalLockTheAnglesStillRebuildTheRotation) {
  for (const double pitch : {M_PI / 2 - 1e-7, -M_PI / 2 + 1e-7, M_PI / 2 - 1e-3}) {
    const Eigen::Quaterniond q = FromRollPitchYaw(-2.0, pitch, 1.0);
    const Eigen::Vector3d a = RollPitchYaw(q);
    EXPECT_LT(AngleBetween(FromRollPitchYaw(a.x(), a.y(), a.z()), q), 1e-7) << pitch;
  }
}

}  // namespace
}  // namespace geometry
}  // namespace autocal
