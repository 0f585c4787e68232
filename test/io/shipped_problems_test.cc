// Every problem file shipped in problems/ reads without error and is listed in
// problems/README.md.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "autocal/io/problem_yaml.h"

namespace autocal {
namespace io {
namespace {

namespace fs = std::filesystem;

TEST(ShippedProblems, EveryFileReadsAndIsListed) {
  const fs::path directory = fs::path(AUTOCAL_SOURCE_DIR) / "problems";
  std::ifstream readme_file(directory / "README.md");
  std::stringstream readme;
  readme << readme_file.rdbuf();
  int count = 0;
  for (const fs::directory_entry& entry : fs::directory_iterator(directory)) {
    if (entry.path().extension() != ".yaml") continue;
    ++count;
    const std::string name = entry.path().filename().string();
    EXPECT_NO_THROW(ReadProblemYaml(entry.path().string())) << name;
    EXPECT_NE(readme.str().find("`" + name + "`"), std::string::npos)
        << name << " is not listed in problems/README.md";
  }
  EXPECT_GE(count, 7);
}

}  // namespace
}  // namespace io
}  // namespace autocal
