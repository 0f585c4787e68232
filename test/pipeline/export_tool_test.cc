// autocal_export as a user runs it: a result directory in, the format's file out (or the
// standard output), exit status 1 with one line for what it cannot do.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "autocal/io/calibration_export.h"
#include "autocal/io/calibration_yaml.h"
#include "support/test_paths.h"
#include "support/tool_runner.h"

namespace autocal {
namespace {

namespace fs = std::filesystem;

using ToolRun = test::ToolOutput;

ToolRun Export(const std::string& flags) { return test::RunTool("autocal_export", flags); }

// A result directory whose calibration.yaml estimated the LiDAR only.
fs::path LidarResult() {
  const fs::path dir = test::OutputDir("lidar_result");
  fs::remove_all(dir);
  fs::create_directories(dir);
  io::CalibrationFile result;
  result.value.p_I_L = Eigen::Vector3d(1.0, 2.0, 3.0);
  result.value.time_offset_lidar_imu_s = 0.025;
  result.uncertainty.T_I_L.sigma_rot_deg = Eigen::Vector3d::Constant(0.01);
  result.uncertainty.T_I_L.sigma_p_m = Eigen::Vector3d::Constant(0.002);
  result.uncertainty.time_offset_lidar_imu_s.sigma = 1e-4;
  io::WriteCalibrationYaml((dir / "calibration.yaml").string(), result);
  return dir;
}

std::string Read(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

TEST(ExportTool, WritesTheFormatsFileFromAResultDirectory) {
  const fs::path result = LidarResult();
  const fs::path out = test::OutputDir("lidar_result") / "fast_lio.yaml";
  const ToolRun run =
      Export("--result=" + result.string() + " --format=fast_lio --output=" + out.string());
  EXPECT_EQ(run.exit_code, 0) << run.text;
  const std::string expected = io::ExportCalibration(
      io::ReadCalibrationYaml((result / "calibration.yaml").string()), io::ExportFormat::kFastLio);
  EXPECT_EQ(Read(out), expected);
  // The standard output by default; the calibration.yaml path works as well.
  const ToolRun to_stdout =
      Export("--result=" + (result / "calibration.yaml").string() + " --format=fast_lio");
  EXPECT_EQ(to_stdout.exit_code, 0);
  EXPECT_EQ(to_stdout.text, expected);
}

// --output naming the result's own calibration.yaml (directly or through a link) would
// replace the calibration by its export: refused, the file kept.
TEST(ExportTool, RefusesToOverwriteTheResult) {
  const fs::path result = LidarResult();
  const std::string calibration = Read(result / "calibration.yaml");
  fs::create_symlink(result / "calibration.yaml", result / "link.yaml");
  for (const fs::path& output :
       {result / "calibration.yaml", result / "." / "calibration.yaml", result / "link.yaml"}) {
    for (const fs::path& input : {result, result / "calibration.yaml"}) {
      const ToolRun run =
          Export("--result=" + input.string() + " --format=fast_lio --output=" + output.string());
      EXPECT_EQ(run.exit_code, 1) << run.text;
      EXPECT_THAT(run.text, ::testing::HasSubstr("is the file --result reads")) << output;
      EXPECT_EQ(Read(result / "calibration.yaml"), calibration) << output;
    }
  }
}

TEST(ExportTool, SaysWhatItCannotDoWithStatusOne) {
  const fs::path result = LidarResult();
  const ToolRun unknown = Export("--result=" + result.string() + " --format=kitti");
  EXPECT_EQ(unknown.exit_code, 1);
  EXPECT_THAT(unknown.text, ::testing::HasSubstr("unknown export format 'kitti'"));
  const ToolRun no_mount = Export("--result=" + result.string() + " --format=autoware");
  EXPECT_EQ(no_mount.exit_code, 1);
  EXPECT_THAT(no_mount.text, ::testing::HasSubstr("T_I_V was not estimated"));
  const ToolRun missing = Export("--result=" + (result / "nothing").string() + " --format=urdf");
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_THAT(missing.text, ::testing::HasSubstr("autocal_export: "));
  const ToolRun no_format = Export("--result=" + result.string());
  EXPECT_EQ(no_format.exit_code, 1);
  EXPECT_THAT(no_format.text, ::testing::HasSubstr("--format is required"));
}

}  // namespace
}  // namespace autocal
