#include "autocal/io/run_status.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "autocal/common/error.h"
#include "support/test_paths.h"

namespace autocal {
namespace io {
namespace {

TEST(RunStatus, RoundTripsEveryField) {
  RunStatus status;
  status.tool = "autocal_calibrate";
  status.vehicle = "car: 017 \"east\"";
  status.datasets = {"/data/a b/2026-11-30", "rel,dir"};
  status.exit_status = 1;
  status.message = "dataset x: line 1\nline 2: 'quoted'";
  status.seconds = 12.25;
  const std::string path = (test::OutputDir("status") / "status.yaml").string();
  WriteRunStatus(path, status);
  const RunStatus read = ReadRunStatus(path);
  EXPECT_EQ(read.tool, status.tool);
  EXPECT_EQ(read.vehicle, status.vehicle);
  EXPECT_EQ(read.datasets, status.datasets);
  EXPECT_EQ(read.exit_status, 1);
  EXPECT_EQ(read.message, status.message);
  EXPECT_EQ(read.seconds, 12.25);
  status.datasets.clear();
  WriteRunStatus(path, status);
  EXPECT_TRUE(ReadRunStatus(path).datasets.empty());
}

// Malformed files name the file, line and column of what is wrong.
TEST(RunStatus, RefusesMalformedFilesWithTheirLocation) {
  const std::string good =
      "format: autocal_status_1\ntool: t\nvehicle: v\ndatasets: []\nexit_status: 0\n"
      "message: \"\"\nseconds: 1\n";
  struct Case {
    std::string text;
    int line;
  };
  const std::vector<Case> cases = {
      {"format: autocal_status_2\ntool: t\n", 1},
      {good.substr(0, good.find("exit_status")) + "exit_status: 300\nmessage: \"\"\nseconds: 1\n",
       5},
      {good.substr(0, good.find("exit_status")) + "exit_status: zero\nmessage: \"\"\nseconds: 1\n",
       5},
      {good + "extra: 1\n", 8},
      {good.substr(0, good.find("seconds")), 1},  // no seconds
  };
  const std::string path = (test::OutputDir("status") / "status.yaml").string();
  for (const Case& c : cases) {
    std::ofstream(path) << c.text;
    try {
      ReadRunStatus(path);
      ADD_FAILURE() << "accepted:\n" << c.text;
    } catch (const ParseError& e) {
      EXPECT_EQ(e.location().file, path);
      EXPECT_EQ(e.location().line, c.line) << e.what();
    }
  }
  EXPECT_THROW(ReadRunStatus(path + ".absent"), Error);
}

}  // namespace
}  // namespace io
}  // namespace autocal
