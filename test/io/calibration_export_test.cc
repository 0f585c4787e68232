// The exporters against hand-worked examples: the skid-steer robot's launch file (the IMU at
// (0, -0.3, 0.52) m in base_link, turned Rz(-90 deg) Rx(+90 deg): `static_transform_publisher
// 0 -0.3 0.52 -1.5708 0 1.5708`, i.e. x y z yaw pitch roll) and a LiDAR turned 90 deg about
// the IMU's z at (1, 2, 3) m, 25 ms late. Each file is read back and its numbers compared.
#include "autocal/io/calibration_export.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <Eigen/Geometry>
#include <cmath>
#include <regex>
#include <string>
#include <vector>

#include "autocal/common/error.h"

namespace autocal {
namespace io {
namespace {

constexpr double kTol = 1e-12;

Eigen::Quaterniond LaunchFileImuInVehicle() {  // R_V_I
  return Eigen::Quaterniond(Eigen::AngleAxisd(-M_PI / 2, Eigen::Vector3d::UnitZ()) *
                            Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitX()));
}
const Eigen::Vector3d kImuInVehicleM(0.0, -0.3, 0.52);  // p_V_I

// A result that estimated the LiDAR, the mount, the antenna and the LiDAR's clock.
CalibrationFile Result() {
  CalibrationFile r;
  r.value.q_I_L = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ());
  r.value.p_I_L = Eigen::Vector3d(1.0, 2.0, 3.0);
  r.value.time_offset_lidar_imu_s = 0.025;
  r.value.q_I_V = LaunchFileImuInVehicle().conjugate();
  r.value.p_I_V = -(r.value.q_I_V * kImuInVehicleM);
  r.value.p_I_A = Eigen::Vector3d(0.1, 0.2, 0.0);
  r.uncertainty.T_I_L.sigma_rot_deg = Eigen::Vector3d::Constant(0.01);
  r.uncertainty.T_I_V.sigma_rot_deg = Eigen::Vector3d::Constant(0.1);
  r.uncertainty.p_I_A_m.sigma = Eigen::Vector3d::Constant(0.01);
  r.uncertainty.time_offset_lidar_imu_s.sigma = 1e-4;
  return r;
}

std::vector<double> Numbers(const YAML::Node& sequence) {
  std::vector<double> out;
  for (const YAML::Node& n : sequence) out.push_back(n.as<double>());
  return out;
}

// The origin (xyz, rpy) of the IMU's joint in a URDF text.
void ImuJointOrigin(const std::string& urdf, Eigen::Vector3d* xyz, Eigen::Vector3d* rpy) {
  const std::regex joint(
      "<joint name=\"imu_link_joint\" type=\"fixed\">\\s*<parent link=\"base_link\"/>\\s*"
      "<child link=\"imu_link\"/>\\s*<origin xyz=\"([^\"]*)\" rpy=\"([^\"]*)\"/>");
  std::smatch m;
  ASSERT_TRUE(std::regex_search(urdf, m, joint)) << urdf;
  ASSERT_EQ(std::sscanf(m[1].str().c_str(), "%lf %lf %lf", &xyz->x(), &xyz->y(), &xyz->z()), 3);
  ASSERT_EQ(std::sscanf(m[2].str().c_str(), "%lf %lf %lf", &rpy->x(), &rpy->y(), &rpy->z()), 3);
}

TEST(ExportCalibration, FastLioHoldsTheLidarInTheImuFrameAndTheClock) {
  const YAML::Node y = YAML::Load(ExportCalibration(Result(), ExportFormat::kFastLio));
  EXPECT_THAT(Numbers(y["mapping"]["extrinsic_T"]), ::testing::ElementsAre(1.0, 2.0, 3.0));
  const std::vector<double> R = Numbers(y["mapping"]["extrinsic_R"]);
  const std::vector<double> expected = {0, -1, 0, 1, 0, 0, 0, 0, 1};  // Rz(90 deg), row-major
  ASSERT_EQ(R.size(), 9u);
  for (size_t i = 0; i < 9; ++i) EXPECT_NEAR(R[i], expected[i], kTol) << i;
  EXPECT_EQ(y["common"]["time_offset_lidar_to_imu"].as<double>(), 0.025);
  EXPECT_FALSE(y["mapping"]["extrinsic_est_en"].as<bool>());
}

// Kalibr's T_cam_imu style is the inverse: T_L_I = [R^T, -R^T p].
TEST(ExportCalibration, KalibrHoldsTheImuToLidarTransformAndTheTimeshift) {
  const YAML::Node y = YAML::Load(ExportCalibration(Result(), ExportFormat::kKalibr));
  const YAML::Node T = y["lidar0"]["T_lidar_imu"];
  ASSERT_EQ(T.size(), 4u);
  const double expected[4][4] = {{0, 1, 0, -2}, {-1, 0, 0, 1}, {0, 0, 1, -3}, {0, 0, 0, 1}};
  for (int i = 0; i < 4; ++i) {
    const std::vector<double> row = Numbers(T[i]);
    ASSERT_EQ(row.size(), 4u);
    for (int j = 0; j < 4; ++j) EXPECT_NEAR(row[j], expected[i][j], kTol) << i << "," << j;
  }
  EXPECT_EQ(y["lidar0"]["timeshift_lidar_imu"].as<double>(), 0.025);
}

// LIO-SAM holds T_L_I: extrinsicRot = R_L_I (= extrinsicRPY), extrinsicTrans = -R_L_I p_I_L.
TEST(ExportCalibration, LioSamHoldsTheImuInTheLidarFrame) {
  const YAML::Node y = YAML::Load(ExportCalibration(Result(), ExportFormat::kLioSam));
  const std::vector<double> expected_R = {0, 1, 0, -1, 0, 0, 0, 0, 1};
  for (const char* key : {"extrinsicRot", "extrinsicRPY"}) {
    const std::vector<double> R = Numbers(y[key]);
    ASSERT_EQ(R.size(), 9u) << key;
    for (size_t i = 0; i < 9; ++i) EXPECT_NEAR(R[i], expected_R[i], kTol) << key << i;
  }
  const std::vector<double> t = Numbers(y["extrinsicTrans"]);
  ASSERT_EQ(t.size(), 3u);
  EXPECT_NEAR(t[0], -2.0, kTol);
  EXPECT_NEAR(t[1], 1.0, kTol);
  EXPECT_NEAR(t[2], -3.0, kTol);
}

// The launch file's numbers come back: x y z and roll pitch yaw = (pi/2, 0, -pi/2).
TEST(ExportCalibration, AutowareGivesTheLaunchFilesPoseOfTheImu) {
  ExportOptions options;
  options.base_link_below_axle_m = 0.0;
  const YAML::Node y = YAML::Load(ExportCalibration(Result(), ExportFormat::kAutoware, options));
  const YAML::Node imu = y["base_link"]["imu_link"];
  EXPECT_NEAR(imu["x"].as<double>(), 0.0, kTol);
  EXPECT_NEAR(imu["y"].as<double>(), -0.3, kTol);
  EXPECT_NEAR(imu["z"].as<double>(), 0.52, kTol);
  EXPECT_NEAR(imu["roll"].as<double>(), M_PI / 2, kTol);
  EXPECT_NEAR(imu["pitch"].as<double>(), 0.0, kTol);
  EXPECT_NEAR(imu["yaw"].as<double>(), -M_PI / 2, kTol);
  // The antenna: p_V_A = R_V_I p_I_A + p_V_I; the IMU's x is the vehicle's -y, its y up.
  const YAML::Node gnss = y["base_link"]["gnss_link"];
  EXPECT_NEAR(gnss["x"].as<double>(), 0.0, kTol);
  EXPECT_NEAR(gnss["y"].as<double>(), -0.3 - 0.1, kTol);
  EXPECT_NEAR(gnss["z"].as<double>(), 0.52 + 0.2, kTol);
  EXPECT_EQ(gnss["roll"].as<std::string>(), "0");
  // The LiDAR composes: T_V_L = T_V_I T_I_L.
  const YAML::Node lidar = y["base_link"]["lidar_link"];
  const Eigen::Vector3d p_V_L =
      LaunchFileImuInVehicle() * Eigen::Vector3d(1, 2, 3) + kImuInVehicleM;
  EXPECT_NEAR(lidar["x"].as<double>(), p_V_L.x(), kTol);
  EXPECT_NEAR(lidar["z"].as<double>(), p_V_L.z(), kTol);
}

// Autoware's base_link is on the ground: by default the mean calibrated rear radius below
// the rear-axle centre when the radii were estimated.
TEST(ExportCalibration, AutowareLowersBaseLinkByTheCalibratedRadius) {
  CalibrationFile r = Result();
  r.value.wheel_radius_left_m = 0.30;
  r.value.wheel_radius_right_m = 0.32;
  r.uncertainty.wheel_radius_left_m.sigma = 1e-4;
  r.uncertainty.wheel_radius_right_m.sigma = 1e-4;
  const std::string text = ExportCalibration(r, ExportFormat::kAutoware);
  EXPECT_NEAR(YAML::Load(text)["base_link"]["imu_link"]["z"].as<double>(), 0.52 + 0.31, kTol);
  EXPECT_THAT(text, ::testing::HasSubstr("mean calibrated rear wheel radius"));
  // URDF and ROS 2 keep the rear-axle centre unless told.
  Eigen::Vector3d xyz, rpy;
  ImuJointOrigin(ExportCalibration(r, ExportFormat::kUrdf), &xyz, &rpy);
  EXPECT_NEAR(xyz.z(), 0.52, kTol);
}

TEST(ExportCalibration, UrdfJointsCarryTheLaunchFilesOrigin) {
  const std::string urdf = ExportCalibration(Result(), ExportFormat::kUrdf);
  Eigen::Vector3d xyz, rpy;
  ImuJointOrigin(urdf, &xyz, &rpy);
  EXPECT_LT((xyz - kImuInVehicleM).norm(), kTol);
  EXPECT_LT((rpy - Eigen::Vector3d(M_PI / 2, 0.0, -M_PI / 2)).norm(), kTol);
  // The clock in the comment, which may not hold "--".
  const size_t open = urdf.find("<!--"), close = urdf.find("-->");
  ASSERT_LT(open, close);
  const std::string comment = urdf.substr(open + 4, close - open - 4);
  EXPECT_THAT(comment, ::testing::HasSubstr("t_imu = t_lidar + 0.025 s"));
  EXPECT_THAT(comment, ::testing::Not(::testing::HasSubstr("--")));
}

TEST(ExportCalibration, Ros2CommandsCarryTheQuaternionOfEachSensor) {
  const std::string script = ExportCalibration(Result(), ExportFormat::kRos2StaticTf);
  const std::regex command(
      "static_transform_publisher --x (\\S+) --y (\\S+) --z (\\S+) --qx (\\S+) --qy (\\S+) "
      "--qz (\\S+) --qw (\\S+) --frame-id base_link --child-frame-id imu_link &");
  std::smatch m;
  ASSERT_TRUE(std::regex_search(script, m, command)) << script;
  const Eigen::Quaterniond q(std::stod(m[7]), std::stod(m[4]), std::stod(m[5]), std::stod(m[6]));
  EXPECT_LT(q.angularDistance(LaunchFileImuInVehicle()), 1e-12);
  EXPECT_NEAR(std::stod(m[2]), -0.3, kTol);
  EXPECT_NEAR(std::stod(m[3]), 0.52, kTol);
  EXPECT_THAT(script, ::testing::HasSubstr("--child-frame-id lidar_link &"));
  EXPECT_THAT(script, ::testing::HasSubstr("--child-frame-id gnss_link &"));
  EXPECT_THAT(script, ::testing::EndsWith("wait\n"));
}

// Without the vehicle the sensors hang from the IMU; frames take the given names.
TEST(ExportCalibration, WithoutTheMountTheImuIsTheRoot) {
  CalibrationFile r = Result();
  r.uncertainty.T_I_V = PoseBlockInfo();
  ExportOptions options;
  options.imu_frame = "imu";
  options.lidar_frame = "velodyne";
  const std::string script = ExportCalibration(r, ExportFormat::kRos2StaticTf, options);
  EXPECT_THAT(script, ::testing::HasSubstr("--x 1 --y 2 --z 3 "));
  EXPECT_THAT(script, ::testing::HasSubstr("--frame-id imu --child-frame-id velodyne &"));
  EXPECT_THAT(script, ::testing::Not(::testing::HasSubstr("base_link")));
}

TEST(ExportCalibration, RefusesWhatTheResultCannotGive) {
  CalibrationFile no_lidar = Result();
  no_lidar.uncertainty.T_I_L = PoseBlockInfo();
  EXPECT_THROW(ExportCalibration(no_lidar, ExportFormat::kKalibr), Error);
  EXPECT_THROW(ExportCalibration(no_lidar, ExportFormat::kFastLio), Error);
  EXPECT_THROW(ExportCalibration(no_lidar, ExportFormat::kLioSam), Error);
  CalibrationFile no_mount = Result();
  no_mount.uncertainty.T_I_V = PoseBlockInfo();
  EXPECT_THROW(ExportCalibration(no_mount, ExportFormat::kAutoware), Error);
  ExportOptions bad;
  bad.lidar_frame = "lidar\" onload=\"x";
  EXPECT_THROW(ExportCalibration(Result(), ExportFormat::kUrdf, bad), Error);
  bad.lidar_frame = "";
  EXPECT_THROW(ExportCalibration(Result(), ExportFormat::kUrdf, bad), Error);
  try {
    ParseExportFormat("kitti");
    ADD_FAILURE() << "an unknown format was accepted";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("known: kalibr, fast_lio, lio_sam, autoware, urdf"));
  }
  EXPECT_EQ(ParseExportFormat("fast_lio"), ExportFormat::kFastLio);
}

}  // namespace
}  // namespace io
}  // namespace autocal
