// autocal_coverage as a user runs it on the shipped rigs: the table on the standard output,
// coverage.md and coverage.svg in --output, exit 0 when every region is covered, 2 when some
// region is short, 1 on bad input.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "support/test_paths.h"
#include "support/tool_runner.h"

namespace autocal {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

std::string Rig(const std::string& name) {
  return (fs::path(AUTOCAL_SOURCE_DIR) / "coverage" / "rigs" / name).string();
}

TEST(CoverageTool, ExitsZeroForACoveringRigAndWritesTheTableAndTheDrawing) {
  const fs::path out = test::OutputDir("full_rig");
  fs::remove_all(out);
  const test::ToolOutput run =
      test::RunTool("autocal_coverage",
                    "--rig=" + Rig("full_rig.yaml") + " --scenario=urban --output=" + out.string());
  EXPECT_EQ(run.exit_code, 0) << run.text;
  EXPECT_THAT(run.text, HasSubstr("emergency stop 19.29 m"));
  EXPECT_THAT(run.text, HasSubstr("| intersection | all around | 50 m around |"));
  EXPECT_TRUE(fs::exists(out / "coverage.md"));
  EXPECT_TRUE(fs::exists(out / "coverage.svg"));
}

// --output replaces a previous coverage output, and refuses any other directory before the
// analysis: its files are left as they were.
TEST(CoverageTool, WritesOnlyIntoItsOwnOutput) {
  const fs::path root = test::OutputDir("coverage_output");
  fs::remove_all(root);
  const std::string rig = "--rig=" + Rig("full_rig.yaml") + " --output=";
  EXPECT_EQ(test::RunTool("autocal_coverage", rig + (root / "out").string()).exit_code, 0);
  EXPECT_EQ(test::RunTool("autocal_coverage", rig + (root / "out").string()).exit_code, 0);
  fs::create_directories(root / "notes");
  std::ofstream(root / "notes" / "todo.txt") << "keep\n";
  const test::ToolOutput refused =
      test::RunTool("autocal_coverage", rig + (root / "notes").string());
  EXPECT_EQ(refused.exit_code, 1) << refused.text;
  EXPECT_THAT(refused.text, HasSubstr("holds 'todo.txt', which is not part of a coverage output"));
  EXPECT_THAT(refused.text, ::testing::Not(HasSubstr("emergency stop")));  // before the analysis
  EXPECT_FALSE(fs::exists(root / "notes" / "coverage.md"));
  EXPECT_TRUE(fs::exists(root / "notes" / "todo.txt"));
}

TEST(CoverageTool, ExitsTwoWhenARegionIsShortAndOneOnBadInput) {
  const test::ToolOutput short_rig = test::RunTool(
      "autocal_coverage", "--rig=" + Rig("front_camera_only.yaml") + " --scenario=highway");
  EXPECT_EQ(short_rig.exit_code, 2) << short_rig.text;
  EXPECT_THAT(short_rig.text, HasSubstr("emergency stop 111.11 m"));
  EXPECT_THAT(short_rig.text, HasSubstr("short: nothing sees"));
  const test::ToolOutput bad =
      test::RunTool("autocal_coverage", "--rig=" + Rig("full_rig.yaml") + " --scenario=rural.yaml");
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_THAT(bad.text, HasSubstr("autocal_coverage: "));
  const test::ToolOutput no_rig = test::RunTool("autocal_coverage", "--scenario=urban");
  EXPECT_EQ(no_rig.exit_code, 1);
  EXPECT_THAT(no_rig.text, HasSubstr("--rig is required"));
}

}  // namespace
}  // namespace autocal
