#include "pipeline/mount_angles.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "autocal/common/units.h"
#include "autocal/geometry/roll_pitch_yaw.h"

namespace autocal {
namespace pipeline {
namespace {

// A level mount: the angles are the tangent's axes, sigma and flags unchanged.
TEST(DisplayedAngleUncertainty, LevelMountKeepsTheTangentsSigmas) {
  const Eigen::Vector3d sigma(0.2, 0.5, 3.0);
  for (const bool parent : {true, false}) {
    const DisplayedAngles angles = DisplayedAngleUncertainty(Eigen::Quaterniond::Identity(), parent,
                                                             sigma, {true, false, true});
    EXPECT_TRUE(angles.sigma_deg.isApprox(sigma, 1e-6)) << angles.sigma_deg.transpose();
    EXPECT_EQ(angles.observable, std::vector<bool>({true, false, true}));
  }
}

// Yawed by psi, about the vehicle's axes: roll moves as cos(psi) dx + sin(psi) dy, pitch as
// -sin(psi) dx + cos(psi) dy, yaw as dz.
TEST(DisplayedAngleUncertainty, YawMixesTheLevelAxes) {
  const double psi = 30.0 * kDegToRad;
  const Eigen::Vector3d sigma(0.2, 0.5, 3.0);
  const DisplayedAngles angles = DisplayedAngleUncertainty(
      geometry::FromRollPitchYaw(0.0, 0.0, psi), true, sigma, {true, true, true});
  const double c = std::cos(psi), s = std::sin(psi);
  EXPECT_NEAR(angles.sigma_deg(0), std::hypot(c * 0.2, s * 0.5), 1e-6);
  EXPECT_NEAR(angles.sigma_deg(1), std::hypot(s * 0.2, c * 0.5), 1e-6);
  EXPECT_NEAR(angles.sigma_deg(2), 3.0, 1e-6);
}

// An IMU mounted on its side and turned -90 deg in yaw, as on the Husky of test1.bag
// (R_V_I: roll 89.5, pitch 0.57, yaw -90 deg): the vehicle's forward axis, well determined,
// moves the pitch; its left axis, held, moves the roll. Shown beside the roll, the forward
// axis' sigma and flag named the wrong angle.
TEST(DisplayedAngleUncertainty, SidewaysMountPutsEachSigmaBesideTheAngleItMoves) {
  const Eigen::Quaterniond mount =
      geometry::FromRollPitchYaw(89.5 * kDegToRad, 0.57 * kDegToRad, -90.0 * kDegToRad);
  const DisplayedAngles angles = DisplayedAngleUncertainty(
      mount, true, Eigen::Vector3d(0.231, 1.879, 5.0), {true, false, false});
  EXPECT_NEAR(angles.sigma_deg(0), 1.879, 0.01);
  EXPECT_NEAR(angles.sigma_deg(1), 0.231, 0.01);
  EXPECT_NEAR(angles.sigma_deg(2), 5.0, 0.1);
  EXPECT_EQ(angles.observable, std::vector<bool>({false, true, false}));
  // One flag for the whole block applies to every angle.
  EXPECT_EQ(DisplayedAngleUncertainty(mount, true, Eigen::Vector3d::Ones(), {false}).observable,
            std::vector<bool>({false, false, false}));
}

}  // namespace
}  // namespace pipeline
}  // namespace autocal
