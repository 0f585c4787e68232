#include "autocal/pipeline/fleet_report.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "autocal/common/units.h"
#include "autocal/io/calibration_yaml.h"
#include "autocal/io/run_status.h"
#include "support/test_paths.h"

namespace autocal {
namespace pipeline {
namespace {

namespace fs = std::filesystem;

// A succeeded run of vehicle `name`: radii, track and mount estimated with sigmas.
std::string Succeeded(const fs::path& root, const std::string& name, double right_radius_m) {
  const fs::path dir = root / name;
  fs::create_directories(dir);
  io::CalibrationFile file;
  file.value.wheel_radius_left_m = 0.3335;
  file.value.wheel_radius_right_m = right_radius_m;
  file.value.track_width_m = 1.62;
  file.value.q_I_V = Eigen::Quaterniond(Eigen::AngleAxisd(0.01, Eigen::Vector3d::UnitZ()));
  file.uncertainty.wheel_radius_left_m.sigma = 3e-5;
  file.uncertainty.wheel_radius_right_m.sigma = 3e-5;
  file.uncertainty.track_width_m.sigma = 3e-3;
  file.uncertainty.T_I_V.sigma_rot_deg = Eigen::Vector3d(1.2, 0.1, 0.1);
  io::WriteCalibrationYaml((dir / "calibration.yaml").string(), file);
  io::RunStatus status;
  status.tool = "autocal_calibrate";
  status.vehicle = name;
  status.datasets = {"/logs/" + name};
  io::WriteRunStatus((dir / "status.yaml").string(), status);
  return dir.string();
}

TEST(FleetReport, GathersValuesFailuresAndOutliers) {
  const fs::path root = test::OutputDir("fleet");
  std::vector<std::string> dirs;
  const double radii[] = {0.33260, 0.33262, 0.33258, 0.33261, 0.33594};  // the last 1 % larger
  for (int i = 0; i < 5; ++i) dirs.push_back(Succeeded(root, "car_" + std::to_string(i), radii[i]));
  // A run that failed, one that never finished, one whose status is damaged.
  fs::create_directories(root / "failed");
  io::RunStatus failed;
  failed.tool = "autocal_calibrate";
  failed.vehicle = "car_failed";
  failed.exit_status = 1;
  failed.message = "dataset /logs/x: the GNSS <track> is too short";
  io::WriteRunStatus((root / "failed" / "status.yaml").string(), failed);
  fs::create_directories(root / "killed");
  fs::create_directories(root / "damaged");
  std::ofstream(root / "damaged" / "status.yaml") << "format: autocal_status_1\ntool: [\n";
  dirs.push_back((root / "failed").string());
  dirs.push_back((root / "killed").string());
  dirs.push_back((root / "damaged").string());

  const FleetReport report = GatherFleet(dirs);
  ASSERT_EQ(report.entries.size(), 8u);
  EXPECT_EQ(report.succeeded, 5u);
  EXPECT_EQ(report.entries[5].vehicle, "car_failed");
  EXPECT_THAT(report.entries[5].failure, ::testing::HasSubstr("too short"));
  EXPECT_THAT(report.entries[6].failure, ::testing::HasSubstr("no status.yaml"));
  EXPECT_THAT(report.entries[7].failure, ::testing::HasSubstr("status.yaml:"));
  // Columns: the estimated blocks only, in file units, the mount as roll, pitch and yaw.
  std::vector<std::string> names;
  for (const FleetColumn& c : report.columns) names.push_back(c.name);
  EXPECT_THAT(names,
              ::testing::ElementsAre("wheel_radius_left_m", "wheel_radius_right_m", "track_width_m",
                                     "q_I_V_roll_deg", "q_I_V_pitch_deg", "q_I_V_yaw_deg"));
  EXPECT_NEAR(report.values[0][5], -0.01 * kRadToDeg, 1e-5);  // R_V_I = R_I_V^T
  ASSERT_EQ(report.outliers.size(), 1u);
  EXPECT_EQ(report.outliers[0].entry, 4u);
  EXPECT_EQ(report.outliers[0].column, 1u);
  EXPECT_THAT(report.outliers[0].text, ::testing::HasSubstr("car_4"));

  const std::string csv = FleetCsv(report);
  EXPECT_THAT(csv,
              ::testing::StartsWith("vehicle,directory,exit_status,message,wheel_radius_left_m,"
                                    "wheel_radius_left_m_sigma,"));
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 9);
  const std::string html = FleetReportHtml(report);
  EXPECT_THAT(html, ::testing::HasSubstr("GNSS &lt;track&gt; is too short"));
  EXPECT_THAT(html, ::testing::HasSubstr("8 runs: 5 calibrated, 3 failed"));
  EXPECT_THAT(html, ::testing::EndsWith("</html>\n"));
}

// A succeeded run of vehicle `name` whose IMU is mounted z down in the vehicle: roll
// `roll_deg` (near +-180), sigma 0.2 deg.
std::string ZDown(const fs::path& root, const std::string& name, double roll_deg) {
  const fs::path dir = root / name;
  fs::create_directories(dir);
  io::CalibrationFile file;
  const Eigen::Quaterniond q_V_I(Eigen::AngleAxisd(roll_deg * kDegToRad, Eigen::Vector3d::UnitX()));
  file.value.q_I_V = q_V_I.conjugate();
  file.uncertainty.T_I_V.sigma_rot_deg = Eigen::Vector3d(0.2, 0.2, 0.2);
  io::WriteCalibrationYaml((dir / "calibration.yaml").string(), file);
  io::RunStatus status;
  status.tool = "autocal_calibrate";
  status.vehicle = name;
  io::WriteRunStatus((dir / "status.yaml").string(), status);
  return dir.string();
}

// Rolls on both sides of +-180 deg are neighbours on the circle: 179.9 and -179.8 lie 0.3 deg
// apart, not 359.7. Compared as plain numbers, the five agreeing mounts flagged two of them
// (median 179.7) and the six hid the one 5 deg off (robust sigma 526 deg).
TEST(FleetReport, ComparesAnglesOnTheCircle) {
  const fs::path root = test::OutputDir("fleet_z_down");
  std::vector<std::string> dirs;
  const double rolls_deg[] = {179.9, -179.8, 179.7, -179.95, 179.85, -175.03};
  for (int i = 0; i < 6; ++i) dirs.push_back(ZDown(root, "car_" + std::to_string(i), rolls_deg[i]));
  EXPECT_TRUE(GatherFleet(std::vector<std::string>(dirs.begin(), dirs.end() - 1)).outliers.empty());
  const FleetReport report = GatherFleet(dirs);
  ASSERT_EQ(report.succeeded, 6u);
  ASSERT_EQ(report.columns[0].name, "q_I_V_roll_deg");
  EXPECT_TRUE(report.columns[0].angle_deg);
  EXPECT_NEAR(report.values[1][0], -179.8, 1e-6);
  ASSERT_EQ(report.outliers.size(), 1u);
  EXPECT_EQ(report.outliers[0].entry, 5u);
  EXPECT_EQ(report.outliers[0].column, 0u);
  EXPECT_NEAR(std::abs(report.outliers[0].median), 179.95, 1e-9);
  EXPECT_NEAR(report.outliers[0].robust_sigma, 1.4826 * 0.2, 1e-9);
  EXPECT_THAT(report.outliers[0].text, ::testing::HasSubstr("24.6 of its own sigma off"));
}

// Each angle carries its own sigma, not the tangent axis' of the same index: an IMU on its side
// turned -90 deg in yaw (the Husky of test1.bag) has the vehicle's left axis (sigma 1.9 deg)
// moving its roll and the forward axis (0.2 deg) its pitch.
TEST(FleetReport, GivesEachAngleItsOwnSigma) {
  const fs::path dir = test::OutputDir("fleet_sideways") / "husky";
  fs::create_directories(dir);
  io::CalibrationFile file;
  const Eigen::Quaterniond q_V_I = Eigen::AngleAxisd(-90.0 * kDegToRad, Eigen::Vector3d::UnitZ()) *
                                   Eigen::AngleAxisd(89.5 * kDegToRad, Eigen::Vector3d::UnitX());
  file.value.q_I_V = q_V_I.conjugate();
  file.uncertainty.T_I_V.sigma_rot_deg = Eigen::Vector3d(0.2, 1.9, 5.0);
  io::WriteCalibrationYaml((dir / "calibration.yaml").string(), file);
  io::RunStatus status;
  status.tool = "autocal_calibrate";
  status.vehicle = "husky";
  io::WriteRunStatus((dir / "status.yaml").string(), status);
  const FleetReport report = GatherFleet({dir.string()});
  ASSERT_EQ(report.columns.size(), 3u);
  ASSERT_EQ(report.columns[0].name, "q_I_V_roll_deg");
  EXPECT_NEAR(report.sigmas[0][0], 1.9, 0.01);
  EXPECT_NEAR(report.sigmas[0][1], 0.2, 0.01);
  EXPECT_NEAR(report.sigmas[0][2], 5.0, 0.01);
}

// A directory given with a trailing slash or dot names its vehicle all the same.
TEST(FleetReport, NamesADirectoryByItsLastComponent) {
  EXPECT_EQ(DirectoryName("runs/car_1"), "car_1");
  EXPECT_EQ(DirectoryName("runs/car_1/"), "car_1");
  EXPECT_EQ(DirectoryName("runs/car_1//"), "car_1");
  EXPECT_EQ(DirectoryName("runs/car_1/."), "car_1");
  EXPECT_EQ(DirectoryName("runs/car_1/x/.."), "car_1");
  EXPECT_EQ(DirectoryName("."), fs::current_path().filename().string());
  EXPECT_EQ(DirectoryName("/"), "");
  const fs::path root = test::OutputDir("fleet_slash");
  fs::create_directories(root / "car_7");  // never finished: no status.yaml, no label
  const FleetReport report = GatherFleet({(root / "car_7").string() + "/"});
  EXPECT_EQ(report.entries[0].vehicle, "car_7");
}

// Fewer than three calibrations give no median to judge against.
TEST(FleetReport, NoOutliersFromTwoRuns) {
  const fs::path root = test::OutputDir("fleet");
  const FleetReport report =
      GatherFleet({Succeeded(root, "a", 0.3326), Succeeded(root, "b", 0.34)});
  EXPECT_TRUE(report.outliers.empty());
  EXPECT_EQ(report.succeeded, 2u);
}

}  // namespace
}  // namespace pipeline
}  // namespace autocal
