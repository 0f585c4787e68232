// pipeline::FormatCalibrationSummary prints rotations as roll, pitch and yaw of the mounting
// (docs/report.md, "Result"), alike for nearly equal rotations.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "autocal/common/units.h"
#include "autocal/geometry/roll_pitch_yaw.h"
#include "autocal/geometry/so3.h"
#include "autocal/pipeline/offline_calibration.h"

namespace autocal {
namespace pipeline {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

// A result whose only estimated block is T_I_V, with R_V_I a half turn -+ 0.0001 deg about an
// axis 1.3 deg from the vehicle's up axis (an IMU mounted upside down).
OfflineCalibrationResult MountResult(double past_half_turn_deg) {
  OfflineCalibrationResult result;
  const Eigen::Quaterniond R_V_I(Eigen::AngleAxisd((180.0 + past_half_turn_deg) * kDegToRad,
                                                   Eigen::Vector3d(0.01, 0.02, 1.0).normalized()));
  result.calibration.value.q_I_V = R_V_I.conjugate();
  result.calibration.uncertainty.T_I_V.sigma_rot_deg = Eigen::Vector3d(0.2, 0.3, 0.4);
  return result;
}

// The summary's line for the mount.
std::string MountLine(const std::string& summary) {
  const size_t begin = summary.find("IMU mount roll pitch yaw (deg)");
  if (begin == std::string::npos) return "";
  return summary.substr(begin, summary.find('\n', begin) - begin);
}

TEST(CalibrationSummary, PrintsTheMountAsRollPitchYawAlikeOnEitherSideOfAHalfTurn) {
  const std::string before = FormatCalibrationSummary(MountResult(-0.0001));
  const std::string after = FormatCalibrationSummary(MountResult(0.0001));
  EXPECT_EQ(MountLine(before), MountLine(after));
  EXPECT_THAT(MountLine(before), HasSubstr("2.292    -1.145   179.977   sigma"));
  EXPECT_THAT(before, Not(HasSubstr("rotation vector")));
}

// The blocks of the other wheel forms get a line each when they were estimated.
TEST(CalibrationSummary, ListsTheBlocksOfTheWheelForm) {
  OfflineCalibrationResult result;
  result.calibration.value.odometry_speed_scale = 0.97;
  result.calibration.value.effective_track_m = 1.04;
  result.calibration.uncertainty.odometry_speed_scale.sigma = 0.002;
  result.calibration.uncertainty.effective_track_m.sigma = 0.01;
  result.calibration.uncertainty.effective_track_m.observable = false;
  const std::string summary = FormatCalibrationSummary(result);
  EXPECT_THAT(summary, HasSubstr("odometry speed scale (%)"));
  EXPECT_THAT(summary, HasSubstr("97.000   sigma   0.200   observable yes"));
  EXPECT_THAT(summary, HasSubstr("1040.0   sigma    10.0   observable no"));
  EXPECT_THAT(summary, Not(HasSubstr("wheel speed scale")));
  EXPECT_THAT(summary, Not(HasSubstr("track width")));
}

}  // namespace
}  // namespace pipeline
}  // namespace autocal
