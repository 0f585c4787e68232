// The block table: its rows reach the right fields of a Calibration, their sizes match their
// manifold, and the file columns derived from it are the names the result files carry.

#include "autocal/sensors/calibration_blocks.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <set>
#include <string>

namespace autocal {
namespace sensors {
namespace {

std::string Joined(const std::vector<std::string>& parts) {
  std::string out;
  for (const std::string& part : parts) out += (out.empty() ? "" : ",") + part;
  return out;
}

TEST(CalibrationBlocks, RowsAreInIdOrderWithUniqueKeys) {
  std::set<std::string> keys;
  for (size_t i = 0; i < CalibrationBlocks().size(); ++i) {
    const CalibrationBlockInfo& block = CalibrationBlocks()[i];
    EXPECT_EQ(static_cast<size_t>(block.id), i) << block.key;
    EXPECT_EQ(&CalibrationBlock(block.id), &block) << block.key;
    EXPECT_EQ(FindCalibrationBlock(block.key), &block) << block.key;
    EXPECT_TRUE(keys.insert(block.key).second) << block.key;
  }
  EXPECT_EQ(FindCalibrationBlock("T_I_L"), nullptr);
}

TEST(CalibrationBlocks, SizesFollowTheManifold) {
  for (const CalibrationBlockInfo& block : CalibrationBlocks()) {
    if (block.manifold == BlockManifold::kRightQuaternion) {
      EXPECT_EQ(block.ambient_size, 4) << block.key;
      EXPECT_EQ(block.tangent_size, 3) << block.key;
      EXPECT_STREQ(block.display_unit, "deg") << block.key;
    } else {
      EXPECT_EQ(block.ambient_size, block.tangent_size) << block.key;
    }
    for (int i = 0; i < block.tangent_size; ++i) {
      ASSERT_NE(block.direction_names[static_cast<size_t>(i)], nullptr) << block.key;
    }
  }
}

// Each row's accessors reach the field its key names, as a pointer into the calibration.
TEST(CalibrationBlocks, AccessorsReachTheNamedField) {
  Calibration c;
  const std::vector<std::pair<CalibrationBlockId, const double*>> fields = {
      {CalibrationBlockId::kLidarRotation, c.q_I_L.coeffs().data()},
      {CalibrationBlockId::kLidarTranslation, c.p_I_L.data()},
      {CalibrationBlockId::kTimeOffset, &c.time_offset_lidar_imu_s},
      {CalibrationBlockId::kWheelRadiusLeft, &c.wheel_radius_left_m},
      {CalibrationBlockId::kWheelRadiusRight, &c.wheel_radius_right_m},
      {CalibrationBlockId::kTrackWidth, &c.track_width_m},
      {CalibrationBlockId::kVehicleRotation, c.q_I_V.coeffs().data()},
      {CalibrationBlockId::kVehicleTranslation, c.p_I_V.data()},
      {CalibrationBlockId::kGnssLeverArm, c.p_I_A.data()},
      {CalibrationBlockId::kWheelSpeedScaleLeft, &c.wheel_speed_scale_left},
      {CalibrationBlockId::kWheelSpeedScaleRight, &c.wheel_speed_scale_right},
      {CalibrationBlockId::kOdometrySpeedScale, &c.odometry_speed_scale},
      {CalibrationBlockId::kEffectiveTrack, &c.effective_track_m},
      {CalibrationBlockId::kWheelTimeOffset, &c.time_offset_wheel_imu_s},
      {CalibrationBlockId::kGnssTimeOffset, &c.time_offset_gnss_imu_s}};
  ASSERT_EQ(fields.size(), CalibrationBlocks().size());
  for (const auto& [id, field] : fields) {
    const CalibrationBlockInfo& block = CalibrationBlock(id);
    EXPECT_EQ(block.values(&c), field) << block.key;
    EXPECT_EQ(block.const_values(c), field) << block.key;
  }
}

// The result files keep their column names: calibration_per_iteration.csv its short ones,
// calibration_over_time.csv the keys.
TEST(CalibrationBlocks, ColumnsAreTheResultFilesNames) {
  std::vector<std::string> iteration, over_time;
  for (const CalibrationBlockInfo& block : CalibrationBlocks()) {
    for (const std::string& c : IterationColumns(block)) iteration.push_back(c);
    for (const std::string& c : ValueColumns(block)) over_time.push_back(c);
  }
  EXPECT_EQ(Joined(iteration),
            "qx,qy,qz,qw,px_m,py_m,pz_m,time_offset_lidar_imu_s,wheel_radius_left_m,"
            "wheel_radius_right_m,track_width_m,qv_x,qv_y,qv_z,qv_w,pv_x_m,pv_y_m,pv_z_m,pa_x_m,"
            "pa_y_m,pa_z_m,wheel_speed_scale_left,wheel_speed_scale_right,odometry_speed_scale,"
            "effective_track_m,time_offset_wheel_imu_s,time_offset_gnss_imu_s");
  EXPECT_EQ(Joined(over_time),
            "q_I_L_x,q_I_L_y,q_I_L_z,q_I_L_w,p_I_L_x_m,p_I_L_y_m,p_I_L_z_m,"
            "time_offset_lidar_imu_s,wheel_radius_left_m,wheel_radius_right_m,track_width_m,"
            "q_I_V_x,q_I_V_y,q_I_V_z,q_I_V_w,p_I_V_x_m,p_I_V_y_m,p_I_V_z_m,"
            "p_I_A_x_m,p_I_A_y_m,p_I_A_z_m,wheel_speed_scale_left,wheel_speed_scale_right,"
            "odometry_speed_scale,effective_track_m,time_offset_wheel_imu_s,"
            "time_offset_gnss_imu_s");
  EXPECT_THAT(ValueColumns(CalibrationBlock(CalibrationBlockId::kVehicleRotation)),
              ::testing::ElementsAre("q_I_V_x", "q_I_V_y", "q_I_V_z", "q_I_V_w"));
}

// Each wheel form determines its own intrinsics; the vehicle frame and the wheel clock belong
// to every form.
TEST(CalibrationBlocks, WheelFormsSelectTheirBlocks) {
  using Id = CalibrationBlockId;
  const auto blocks_of = [](WheelForm form) {
    std::vector<std::string> keys;
    for (const CalibrationBlockInfo& block : CalibrationBlocks()) {
      if (block.sensor == BlockSensor::kWheel && BlockInWheelForm(block.id, form))
        keys.push_back(block.key);
    }
    return Joined(keys);
  };
  EXPECT_EQ(blocks_of(WheelForm::kAngularRates),
            "wheel_radius_left_m,wheel_radius_right_m,track_width_m,q_I_V,p_I_V,"
            "time_offset_wheel_imu_s");
  EXPECT_EQ(blocks_of(WheelForm::kLinearSpeeds),
            "track_width_m,q_I_V,p_I_V,wheel_speed_scale_left,wheel_speed_scale_right,"
            "time_offset_wheel_imu_s");
  EXPECT_EQ(blocks_of(WheelForm::kSpeedYawRate),
            "q_I_V,p_I_V,odometry_speed_scale,effective_track_m,time_offset_wheel_imu_s");
  EXPECT_TRUE(BlockInWheelForm(Id::kLidarRotation, WheelForm::kSpeedYawRate));
}

// The sensors.yaml spelling of every form reads back, and names its file.
TEST(CalibrationBlocks, WheelFormNamesRoundTrip) {
  for (WheelForm form :
       {WheelForm::kAngularRates, WheelForm::kLinearSpeeds, WheelForm::kSpeedYawRate}) {
    WheelForm read = WheelForm::kAngularRates;
    ASSERT_TRUE(ParseWheelForm(WheelFormName(form), &read)) << WheelFormName(form);
    EXPECT_EQ(read, form);
  }
  WheelForm unused;
  EXPECT_FALSE(ParseWheelForm("twist", &unused));
  EXPECT_STREQ(WheelFormFile(WheelForm::kLinearSpeeds), "wheel_speed.csv");
  EXPECT_STREQ(WheelFormFile(WheelForm::kSpeedYawRate), "odometry.csv");
}

}  // namespace
}  // namespace sensors
}  // namespace autocal
