#include "autocal/io/calibration_block_fields.h"

#include <gtest/gtest.h>

#include <set>
#include <string>
#include <utility>
#include <vector>

namespace autocal {
namespace io {
namespace {

// A value per block and direction that no other block shares.
Eigen::VectorXd Distinct(const sensors::CalibrationBlockInfo& block) {
  Eigen::VectorXd v(block.tangent_size);
  for (int k = 0; k < block.tangent_size; ++k) {
    v(k) = 1.0 + static_cast<int>(block.id) + 0.1 * (k + 1);
  }
  return v;
}

// Every block has a field of its own in a problem: setting all of them with distinct values
// reads each one back unchanged.
TEST(CalibrationBlockFields, EveryBlockHasItsOwnProblemSetting) {
  ProblemCalibration problem;
  for (const sensors::CalibrationBlockInfo& block : sensors::CalibrationBlocks()) {
    SetBlockSetting(block.id, {BlockMode::kPrior, Distinct(block)}, &problem);
  }
  std::set<std::string> keys;
  for (const sensors::CalibrationBlockInfo& block : sensors::CalibrationBlocks()) {
    const BlockModeAndSigma read = BlockSettingIn(problem, block.id);
    EXPECT_EQ(read.mode, BlockMode::kPrior) << block.key;
    EXPECT_EQ(read.prior_sigma, Distinct(block)) << block.key;
    keys.insert(ProblemKey(block.id));
  }
  EXPECT_EQ(keys.size(), sensors::CalibrationBlocks().size());
  EXPECT_EQ(problem.T_I_V.rotation.prior_sigma(2),
            Distinct(sensors::CalibrationBlock(sensors::CalibrationBlockId::kVehicleRotation))(2));
  EXPECT_STREQ(ProblemKey(sensors::CalibrationBlockId::kGnssLeverArm), "p_I_A_m");
}

// The same for an uncertainty; a pose's two halves share six flags, rotation first.
TEST(CalibrationBlockFields, EveryBlockHasItsOwnUncertainty) {
  CalibrationUncertainty u;
  for (const sensors::CalibrationBlockInfo& block : sensors::CalibrationBlocks()) {
    EXPECT_FALSE(UncertaintyIn(u, block.id).sigma) << block.key;
    std::vector<bool> flags(static_cast<size_t>(block.tangent_size), true);
    flags.back() = false;
    SetBlockUncertainty(block.id, Distinct(block), &flags, &u);
  }
  for (const sensors::CalibrationBlockInfo& block : sensors::CalibrationBlocks()) {
    const BlockUncertainty read = UncertaintyIn(u, block.id);
    ASSERT_TRUE(read.sigma) << block.key;
    EXPECT_EQ(*read.sigma, Distinct(block)) << block.key;
    ASSERT_EQ(read.observable.size(), static_cast<size_t>(block.tangent_size)) << block.key;
    EXPECT_FALSE(read.observable.back()) << block.key;
    EXPECT_TRUE(read.observable.front() || block.tangent_size == 1) << block.key;
  }
  EXPECT_EQ(u.T_I_L.observable, std::vector<bool>({true, true, false, true, true, false}));
}

// Each block lands in the field of its own name: an oracle written out here, so that two
// blocks swapped consistently in both maps (left and right, the two clocks) are caught.
TEST(CalibrationBlockFields, EachBlockIsItsNamedField) {
  using Id = sensors::CalibrationBlockId;
  ProblemCalibration p;
  CalibrationUncertainty u;
  for (const sensors::CalibrationBlockInfo& block : sensors::CalibrationBlocks()) {
    SetBlockSetting(block.id, {BlockMode::kPrior, Distinct(block)}, &p);
    SetBlockUncertainty(block.id, Distinct(block), nullptr, &u);
  }
  const auto scalar = [](Id id) { return Distinct(sensors::CalibrationBlock(id))(0); };
  const auto vector = [](Id id) {
    return Eigen::Vector3d(Distinct(sensors::CalibrationBlock(id)));
  };
  const std::pair<Id, std::pair<const ScalarBlockSetting*, const ScalarBlockInfo*>> scalars[] = {
      {Id::kTimeOffset, {&p.time_offset_lidar_imu_s, &u.time_offset_lidar_imu_s}},
      {Id::kWheelRadiusLeft, {&p.wheel_radius_left_m, &u.wheel_radius_left_m}},
      {Id::kWheelRadiusRight, {&p.wheel_radius_right_m, &u.wheel_radius_right_m}},
      {Id::kTrackWidth, {&p.track_width_m, &u.track_width_m}},
      {Id::kWheelSpeedScaleLeft, {&p.wheel_speed_scale_left, &u.wheel_speed_scale_left}},
      {Id::kWheelSpeedScaleRight, {&p.wheel_speed_scale_right, &u.wheel_speed_scale_right}},
      {Id::kOdometrySpeedScale, {&p.odometry_speed_scale, &u.odometry_speed_scale}},
      {Id::kEffectiveTrack, {&p.effective_track_m, &u.effective_track_m}},
      {Id::kWheelTimeOffset, {&p.time_offset_wheel_imu_s, &u.time_offset_wheel_imu_s}},
      {Id::kGnssTimeOffset, {&p.time_offset_gnss_imu_s, &u.time_offset_gnss_imu_s}}};
  for (const auto& [id, fields] : scalars) {
    SCOPED_TRACE(sensors::CalibrationBlock(id).key);
    EXPECT_EQ(fields.first->prior_sigma, scalar(id));
    EXPECT_EQ(*fields.second->sigma, scalar(id));
    EXPECT_STREQ(ProblemKey(id), sensors::CalibrationBlock(id).key);
  }
  EXPECT_EQ(p.T_I_L.rotation.prior_sigma, vector(Id::kLidarRotation));
  EXPECT_EQ(p.T_I_L.translation.prior_sigma, vector(Id::kLidarTranslation));
  EXPECT_EQ(p.T_I_V.rotation.prior_sigma, vector(Id::kVehicleRotation));
  EXPECT_EQ(p.T_I_V.translation.prior_sigma, vector(Id::kVehicleTranslation));
  EXPECT_EQ(p.p_I_A_m.prior_sigma, vector(Id::kGnssLeverArm));
  EXPECT_EQ(*u.T_I_L.sigma_rot_deg, vector(Id::kLidarRotation));
  EXPECT_EQ(*u.T_I_L.sigma_p_m, vector(Id::kLidarTranslation));
  EXPECT_EQ(*u.T_I_V.sigma_rot_deg, vector(Id::kVehicleRotation));
  EXPECT_EQ(*u.T_I_V.sigma_p_m, vector(Id::kVehicleTranslation));
  EXPECT_EQ(*u.p_I_A_m.sigma, vector(Id::kGnssLeverArm));
  EXPECT_STREQ(ProblemKey(Id::kVehicleTranslation), "T_I_V translation");
}

// A pose stated observable or not as a whole keeps that for the half not set.
TEST(CalibrationBlockFields, APoseFlagForTheWholeBlockStaysWithTheOtherHalf) {
  CalibrationUncertainty u;
  u.T_I_L.observable = {false};
  const std::vector<bool> rotation = {true, true, true};
  SetBlockUncertainty(sensors::CalibrationBlockId::kLidarRotation, Eigen::Vector3d::Ones(),
                      &rotation, &u);
  EXPECT_EQ(u.T_I_L.observable, std::vector<bool>({true, true, true, false, false, false}));
}

}  // namespace
}  // namespace io
}  // namespace autocal
