// Rig and scenario files (docs/coverage.md): the shipped scenarios hold the course's values
// (the presets), a LiDAR placed by a calibration result, and errors with file:line:column.
#include "autocal/io/coverage_yaml.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "autocal/common/error.h"
#include "autocal/io/calibration_yaml.h"
#include "support/test_paths.h"

namespace autocal {
namespace io {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

fs::path Write(const std::string& name, const std::string& text) {
  const fs::path path = test::OutputDir("coverage") / name;
  fs::create_directories(path.parent_path());
  std::ofstream(path) << text;
  return path;
}

std::string Message(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "accepted";
}

TEST(CoverageYaml, ShippedScenariosAreTheCoursesPresets) {
  for (const char* name : {"highway", "urban"}) {
    const coverage::Scenario file = ReadScenarioYaml(
        (fs::path(AUTOCAL_SOURCE_DIR) / "coverage" / (std::string(name) + ".yaml")).string());
    const coverage::Scenario preset = ScenarioPreset(name);
    EXPECT_NEAR(file.speed_m_s, preset.speed_m_s, 1e-12) << name;
    EXPECT_EQ(file.maneuvers, preset.maneuvers) << name;
    EXPECT_EQ(file.aggressive_deceleration_m_s2, preset.aggressive_deceleration_m_s2);
    EXPECT_EQ(file.normal_deceleration_m_s2, preset.normal_deceleration_m_s2);
    EXPECT_EQ(file.lane_width_m, preset.lane_width_m);
    EXPECT_EQ(file.time_gap_s, preset.time_gap_s);
    EXPECT_EQ(file.side_range_m, preset.side_range_m);
    EXPECT_EQ(file.omni_range_m, preset.omni_range_m);
  }
  EXPECT_THROW(ScenarioPreset("rural"), Error);
}

// The LiDAR of a result: T_V_L = T_V_I T_I_L, raised by the mean calibrated rear radius.
TEST(CoverageYaml, PlacesTheCalibratedLidar) {
  CalibrationFile result;
  result.value.q_I_V = Eigen::Quaterniond(Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitZ()));
  result.value.p_I_V = Eigen::Vector3d(-1.3, 0.0, -0.8);
  result.value.q_I_L = Eigen::Quaterniond(Eigen::AngleAxisd(0.05, Eigen::Vector3d::UnitY()));
  result.value.p_I_L = Eigen::Vector3d(0.2, 0.0, 1.0);
  result.value.wheel_radius_left_m = 0.33;
  result.value.wheel_radius_right_m = 0.35;
  result.uncertainty.wheel_radius_left_m.sigma = 1e-4;
  result.uncertainty.wheel_radius_right_m.sigma = 1e-4;
  WriteCalibrationYaml((test::OutputDir("coverage") / "calibration.yaml").string(), result);
  const fs::path rig = Write("rig.yaml",
                             "body: {rear_m: -1, front_m: 3.8, half_width_m: 0.95, height_m: 1.5}\n"
                             "calibration: {file: calibration.yaml}\n"
                             "sensors:\n"
                             "  - {name: lidar, type: lidar, pose_from_calibration: lidar,\n"
                             "     hfov_deg: 360, vfov_deg: [-25, 15], range_m: 100}\n");
  const coverage::Rig r = ReadRigYaml(rig.string());
  ASSERT_EQ(r.sensors.size(), 1u);
  const Eigen::Quaterniond q_V_I = result.value.q_I_V.conjugate();
  const Eigen::Vector3d expected =
      q_V_I * (result.value.p_I_L - result.value.p_I_V) + Eigen::Vector3d(0.0, 0.0, 0.34);
  EXPECT_LT((r.sensors[0].position_m - expected).norm(), 1e-12);
  EXPECT_NEAR(r.sensors[0].yaw_rad, -0.1, 1e-12);  // R_V_L = Rz(-0.1) Ry(0.05)
  EXPECT_NEAR(r.sensors[0].pitch_rad, 0.05, 1e-12);
  EXPECT_EQ(r.name, "rig");
}

TEST(CoverageYaml, NamesTheLineAndColumnOfAProblem) {
  const std::string body = "body: {rear_m: -1, front_m: 3.8, half_width_m: 0.95, height_m: 1.5}\n";
  EXPECT_THAT(Message([&] {
                ReadRigYaml(Write("bad_type.yaml",
                                  body + "sensors:\n  - {name: s, type: sonar, position_m: "
                                         "[0, 0, 1], hfov_deg: 90, vfov_deg: [-5, 5], "
                                         "range_m: 5}\n")
                                .string());
              }),
              HasSubstr("bad_type.yaml:3:"));
  EXPECT_THAT(Message([&] {
                ReadRigYaml(Write("no_calibration.yaml",
                                  body + "sensors:\n  - {name: s, type: lidar, "
                                         "pose_from_calibration: lidar, hfov_deg: 360, "
                                         "vfov_deg: [-5, 5], range_m: 5}\n")
                                .string());
              }),
              HasSubstr("needs the rig's calibration key"));
  EXPECT_THAT(Message([&] {
                ReadScenarioYaml(
                    Write("bad_scenario.yaml", "speed_kmh: 50\nmaneuvers: [parking]\n").string());
              }),
              HasSubstr("bad_scenario.yaml:2:12: coverage: unknown manoeuvre 'parking'"));
  EXPECT_THAT(
      Message([&] {
        ReadScenarioYaml(Write("slow.yaml", "speed_kmh: 0\nmaneuvers: [roundabout]\n").string());
      }),
      HasSubstr("slow.yaml:1:12"));
}

}  // namespace
}  // namespace io
}  // namespace autocal
