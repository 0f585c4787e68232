// The blocks an offline calibration estimates, derived from the block table and the problem:
// which, in what order, with which prior; and the uncertainty section filled from them.

#include "pipeline/problem_blocks.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>

#include "autocal/common/units.h"
#include "autocal/geometry/so3.h"

namespace autocal {
namespace pipeline {
namespace {

using Id = sensors::CalibrationBlockId;

std::vector<Id> Ids(const std::vector<estimation::EstimatedBlock>& blocks) {
  std::vector<Id> out;
  for (const estimation::EstimatedBlock& b : blocks) out.push_back(b.id);
  return out;
}

io::SensorsConfig Nominal() {
  io::SensorsConfig sensors;
  sensors.nominal_calibration.q_I_L = geometry::Exp(Eigen::Vector3d(0.01, -0.02, 1.5));
  sensors.nominal_calibration.p_I_L = Eigen::Vector3d(0.3, -0.1, 0.5);
  sensors.nominal_calibration.track_width_m = 1.55;
  return sensors;
}

TEST(ProblemBlocks, EstimatedBlocksFollowTheTableAndTheSensorsUsed) {
  const io::Problem problem;  // every block estimated
  const io::SensorsConfig sensors = Nominal();
  sensors::Calibration c = sensors.nominal_calibration;
  const OfflineCalibrationOptions options;
  EXPECT_THAT(
      Ids(EstimatedBlocks(problem, sensors, options, true, true, &c)),
      ::testing::ElementsAre(Id::kLidarRotation, Id::kLidarTranslation, Id::kTimeOffset,
                             Id::kWheelRadiusLeft, Id::kWheelRadiusRight, Id::kTrackWidth,
                             Id::kVehicleRotation, Id::kVehicleTranslation, Id::kGnssLeverArm));
  EXPECT_THAT(Ids(EstimatedBlocks(problem, sensors, options, false, true, &c)),
              ::testing::ElementsAre(Id::kLidarRotation, Id::kLidarTranslation, Id::kTimeOffset,
                                     Id::kGnssLeverArm));
  io::Problem fixed = problem;
  fixed.calibration.time_offset_lidar_imu_s.mode = io::BlockMode::kFixed;
  fixed.calibration.T_I_V.rotation.mode = io::BlockMode::kFixed;
  fixed.calibration.wheel_radius_shared = true;
  const std::vector<estimation::EstimatedBlock> blocks =
      EstimatedBlocks(fixed, sensors, options, true, false, &c);
  EXPECT_THAT(Ids(blocks), ::testing::ElementsAre(Id::kLidarRotation, Id::kLidarTranslation,
                                                  Id::kWheelRadiusLeft, Id::kTrackWidth,
                                                  Id::kVehicleTranslation));
  EXPECT_EQ(blocks[2].name, "rear wheel radius (both wheels)");
  EXPECT_THAT(blocks[2].direction_names, ::testing::ElementsAre(blocks[2].name));
}

// The wheel intrinsics that take part are those of the dataset's wheel form; their priors
// default to the weak ones of problem_blocks.cc, a stated nominal sigma wins.
TEST(ProblemBlocks, WheelBlocksFollowTheWheelForm) {
  const io::Problem problem;  // every block estimated
  io::SensorsConfig sensors = Nominal();
  sensors.wheel = sensors::WheelConfig();
  sensors.wheel->form = sensors::WheelForm::kSpeedYawRate;
  sensors.nominal_calibration.effective_track_m = 0.9;
  sensors.nominal_uncertainty.odometry_speed_scale.sigma = 0.02;
  sensors::Calibration c = sensors.nominal_calibration;
  const OfflineCalibrationOptions options;
  const std::vector<estimation::EstimatedBlock> twist =
      EstimatedBlocks(problem, sensors, options, true, false, &c);
  EXPECT_THAT(Ids(twist),
              ::testing::ElementsAre(Id::kLidarRotation, Id::kLidarTranslation, Id::kTimeOffset,
                                     Id::kVehicleRotation, Id::kVehicleTranslation,
                                     Id::kOdometrySpeedScale, Id::kEffectiveTrack));
  EXPECT_EQ(twist[5].prior(0), 1.0);
  EXPECT_EQ(twist[5].prior_sigma(0), 0.02);
  EXPECT_EQ(twist[6].prior(0), 0.9);
  // b_eff's default prior and limit follow its nominal value (0.75 and 5 % of it).
  EXPECT_DOUBLE_EQ(twist[6].prior_sigma(0), 0.75 * 0.9);
  EXPECT_DOUBLE_EQ(twist[6].max_observable_sigma, 0.05 * 0.9);
  sensors.nominal_calibration.effective_track_m = 0.04;
  const std::vector<estimation::EstimatedBlock> narrow =
      EstimatedBlocks(problem, sensors, options, true, false, &c);
  EXPECT_EQ(narrow[6].prior_sigma(0), options.default_track_width_prior_sigma_m);
  EXPECT_EQ(narrow[6].max_observable_sigma, options.max_observable_track_width_sigma_m);
  sensors.wheel->form = sensors::WheelForm::kLinearSpeeds;
  EXPECT_THAT(Ids(EstimatedBlocks(problem, sensors, options, true, false, &c)),
              ::testing::ElementsAre(Id::kLidarRotation, Id::kLidarTranslation, Id::kTimeOffset,
                                     Id::kTrackWidth, Id::kVehicleRotation, Id::kVehicleTranslation,
                                     Id::kWheelSpeedScaleLeft, Id::kWheelSpeedScaleRight));
  // The uncertainty of a result reaches the form's blocks.
  io::CalibrationUncertainty u;
  SetUncertainty(Id::kEffectiveTrack, Eigen::VectorXd::Constant(1, 0.004), nullptr, &u);
  SetUncertainty(Id::kWheelSpeedScaleRight, Eigen::VectorXd::Constant(1, 0.001), nullptr, &u);
  EXPECT_EQ(u.effective_track_m.sigma, 0.004);
  EXPECT_EQ(u.wheel_speed_scale_right.sigma, 0.001);
}

// The prior is the nominal value; its sigma the problem's in prior mode (degrees to radians),
// else the dataset's stated one, else the options' default; the limits from the options.
TEST(ProblemBlocks, PriorsComeFromTheProblemTheDatasetOrTheDefaults) {
  io::Problem problem;
  problem.calibration.T_I_L.rotation = {io::BlockMode::kPrior, Eigen::Vector3d(1.0, 2.0, 4.0)};
  io::SensorsConfig sensors = Nominal();
  sensors.nominal_uncertainty.T_I_L.sigma_p_m = Eigen::Vector3d(0.01, 0.02, 0.03);
  sensors::Calibration c = sensors.nominal_calibration;
  c.p_I_L.x() += 0.5;  // the start differs from the prior
  const OfflineCalibrationOptions options;
  const std::vector<estimation::EstimatedBlock> blocks =
      EstimatedBlocks(problem, sensors, options, true, true, &c);
  const estimation::EstimatedBlock& rotation = blocks[0];
  EXPECT_EQ(rotation.data, c.q_I_L.coeffs().data());
  EXPECT_EQ(rotation.prior, Eigen::VectorXd(sensors.nominal_calibration.q_I_L.coeffs()));
  EXPECT_TRUE(rotation.prior_sigma.isApprox(Eigen::Vector3d(1.0, 2.0, 4.0) * kDegToRad, 1e-15));
  EXPECT_NEAR(rotation.max_observable_sigma, options.max_observable_rotation_sigma_deg * kDegToRad,
              1e-18);
  const estimation::EstimatedBlock& translation = blocks[1];
  EXPECT_EQ(translation.data, c.p_I_L.data());
  EXPECT_EQ(translation.prior, Eigen::VectorXd(sensors.nominal_calibration.p_I_L));
  EXPECT_EQ(translation.prior_sigma, Eigen::VectorXd(Eigen::Vector3d(0.01, 0.02, 0.03)));
  const estimation::EstimatedBlock& offset = blocks[2];
  EXPECT_EQ(offset.prior_sigma(0), options.default_time_offset_prior_sigma_s);
  EXPECT_EQ(offset.max_observable_sigma, options.max_observable_time_offset_sigma_s);
  EXPECT_EQ(offset.max_posterior_to_prior_sigma, options.max_posterior_to_prior_sigma);
  const estimation::EstimatedBlock& lever_arm = blocks.back();
  EXPECT_EQ(lever_arm.prior_sigma,
            Eigen::VectorXd::Constant(3, options.default_translation_prior_sigma_m));
  EXPECT_EQ(lever_arm.max_observable_sigma, options.max_observable_lever_arm_sigma_m);
}

// Sigmas go to the calibration file in its units (degrees for rotations), the flags of a
// pose block into its six (rotation, then translation).
TEST(ProblemBlocks, FillUncertaintyWritesEachBlocksSection) {
  io::Problem problem;
  problem.calibration.T_I_L.rotation.mode = io::BlockMode::kFixed;
  const io::SensorsConfig sensors = Nominal();
  sensors::Calibration c = sensors.nominal_calibration;
  const std::vector<estimation::EstimatedBlock> blocks =
      EstimatedBlocks(problem, sensors, OfflineCalibrationOptions(), true, true, &c);
  estimation::BlockObservability observability;
  for (const estimation::EstimatedBlock& b : blocks) {
    observability.sigma.push_back(b.size == 3
                                      ? Eigen::VectorXd(Eigen::Vector3d(0.001, 0.002, 0.003))
                                      : Eigen::VectorXd::Constant(1, 0.004));
    observability.observable.push_back(std::vector<bool>(static_cast<size_t>(b.size), true));
  }
  observability.observable[0][2] = false;      // T_I_L translation z
  observability.observable.back()[1] = false;  // p_I_A y
  io::CalibrationUncertainty u;
  FillUncertainty(blocks, observability, &u);
  EXPECT_FALSE(u.T_I_L.sigma_rot_deg.has_value());
  ASSERT_TRUE(u.T_I_L.sigma_p_m.has_value());
  EXPECT_EQ(*u.T_I_L.sigma_p_m, Eigen::Vector3d(0.001, 0.002, 0.003));
  // The fixed rotation was not estimated: not observable (it used to read true).
  EXPECT_THAT(u.T_I_L.observable, ::testing::ElementsAre(false, false, false, true, true, false));
  ASSERT_TRUE(u.T_I_V.sigma_rot_deg.has_value());
  EXPECT_NEAR((*u.T_I_V.sigma_rot_deg)(2), 0.003 * kRadToDeg, 1e-15);
  EXPECT_EQ(u.track_width_m.sigma, 0.004);
  EXPECT_EQ(u.track_width_m.observable, true);
  EXPECT_THAT(u.p_I_A_m.observable, ::testing::ElementsAre(true, false, true));
  EXPECT_EQ(*u.p_I_A_m.sigma, Eigen::Vector3d(0.001, 0.002, 0.003));
}

}  // namespace
}  // namespace pipeline
}  // namespace autocal
