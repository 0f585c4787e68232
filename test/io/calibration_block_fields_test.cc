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

// A pose half the problem fixes gets no sigma and is not estimated: when the other half is
// written with flags, the fixed half's three flags are false, never the "true" that an empty
// list stood for. A half given a sigma later without flags counts as observable again.
TEST(CalibrationBlockFields, AFixedPoseHalfIsNotObservable) {
  using Id = sensors::CalibrationBlockId;
  CalibrationUncertainty u;
  const std::vector<bool> flags = {true, true, false};
  SetBlockUncertainty(Id::kLidarTranslation, Eigen::Vector3d(0.03, 0.03, 0.03), &flags, &u);
  EXPECT_FALSE(u.T_I_L.sigma_rot_deg);
  EXPECT_EQ(u.T_I_L.observable, std::vector<bool>({false, false, false, true, true, false}));
  EXPECT_EQ(UncertaintyIn(u, Id::kLidarRotation).observable,
            std::vector<bool>({false, false, false}));
  SetBlockUncertainty(Id::kVehicleRotation, Eigen::Vector3d(0.1, 0.1, 0.1), &flags, &u);
  EXPECT_EQ(u.T_I_V.observable, std::vector<bool>({true, true, false, false, false, false}));
  // The other half estimated after all, without flags: observable, as a pose without flags.
  SetBlockUncertainty(Id::kVehicleTranslation, Eigen::Vector3d(0.02, 0.02, 0.02), nullptr, &u);
  EXPECT_EQ(u.T_I_V.observable, std::vector<bool>({true, true, false, true, true, true}));
  // With flags of its own they replace those.
  SetBlockUncertainty(Id::kLidarRotation, Eigen::Vector3d(0.1, 0.1, 0.1), &flags, &u);
  EXPECT_EQ(u.T_I_L.observable, std::vector<bool>({true, true, false, true, true, false}));
  // A half estimated before the other is written with flags keeps the empty list's meaning.
  CalibrationUncertainty both;
  SetBlockUncertainty(Id::kLidarRotation, Eigen::Vector3d(0.1, 0.1, 0.1), nullptr, &both);
  SetBlockUncertainty(Id::kLidarTranslation, Eigen::Vector3d(0.03, 0.03, 0.03), &flags, &both);
  EXPECT_EQ(both.T_I_L.observable, std::vector<bool>({true, true, true, true, true, false}));
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
