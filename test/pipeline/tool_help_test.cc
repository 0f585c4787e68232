// --help of every command-line tool (tools/tool_help.h): the usage line and the tool's own
// flags, short, with the logging flags left to --helpfull.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <regex>
#include <string>
#include <vector>

#include "support/tool_runner.h"

namespace autocal {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::Not;

const char* const kTools[] = {"autocal_calibrate", "autocal_coverage", "autocal_estimate",
                              "autocal_evaluate",  "autocal_export",   "autocal_import",
                              "autocal_register",  "autocal_simulate"};

using Output = test::ToolOutput;
using test::RunTool;

// The names of the flags tools/<tool>.cc defines (DEFINE_<type>(name, ...)).
std::vector<std::string> DefinedFlags(const std::string& tool) {
  std::ifstream in(fs::path(AUTOCAL_SOURCE_DIR) / "tools" / (tool + ".cc"));
  const std::string source((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::regex define(R"(DEFINE_[a-z0-9]+\(\s*([a-z0-9_]+)\s*,)");
  std::vector<std::string> names;
  for (auto it = std::sregex_iterator(source.begin(), source.end(), define);
       it != std::sregex_iterator(); ++it) {
    names.push_back((*it)[1].str());
  }
  return names;
}

int Lines(const std::string& text) {
  return static_cast<int>(std::count(text.begin(), text.end(), '\n'));
}

TEST(ToolHelp, ListsTheToolsOwnFlagsAndNoLoggingFlags) {
  for (const char* tool : kTools) {
    const std::vector<std::string> flags = DefinedFlags(tool);
    ASSERT_GE(flags.size(), 3u) << tool;
    for (const char* help : {"--help", "-h", "-help", "--helpshort"}) {
      SCOPED_TRACE(std::string(tool) + " " + help);
      const Output out = RunTool(tool, help);
      EXPECT_EQ(out.exit_code, 0) << out.text;
      // The usage message, one line per own flag and a few lines around them.
      EXPECT_LE(Lines(out.text), static_cast<int>(flags.size()) + 20) << out.text;
      EXPECT_THAT(out.text, HasSubstr(tool));
      for (const std::string& flag : flags) EXPECT_THAT(out.text, HasSubstr("--" + flag + "="));
      EXPECT_THAT(out.text, Not(HasSubstr("logtostderr")));
      EXPECT_THAT(out.text, Not(HasSubstr("flagfile")));
      EXPECT_THAT(out.text, HasSubstr("--helpfull"));
    }
  }
}

TEST(ToolHelp, HelpAfterOtherFlagsIsStillHelp) {
  const Output out = RunTool("autocal_simulate", "--duration_s 5 --seed=3 --help");
  EXPECT_EQ(out.exit_code, 0) << out.text;
  EXPECT_THAT(out.text, HasSubstr("--duration_s="));
}

TEST(ToolHelp, AValueThatLooksLikeHelpIsAValue) {
  // "-h" is the value of --out here, so the tool runs (and refuses the stray argument before
  // any work) instead of printing its help.
  const Output out = RunTool("autocal_simulate", "--out -h stray");
  EXPECT_NE(out.exit_code, 0) << out.text;
  EXPECT_THAT(out.text, HasSubstr("unexpected argument 'stray'"));
  EXPECT_THAT(out.text, Not(HasSubstr("Flags of autocal_simulate")));
}

TEST(ToolHelp, HelpfullStillListsEveryFlag) {
  // autocal_calibrate links glog, whose flags gflags lists in full.
  const Output full = RunTool("autocal_calibrate", "--helpfull");
  EXPECT_THAT(full.text, HasSubstr("logtostderr"));
  EXPECT_THAT(full.text, HasSubstr("flagfile"));
  EXPECT_THAT(full.text, HasSubstr("threads"));
  const Output short_help = RunTool("autocal_calibrate", "--help");
  EXPECT_LT(Lines(short_help.text) * 4, Lines(full.text)) << short_help.text;
}

}  // namespace
}  // namespace autocal
