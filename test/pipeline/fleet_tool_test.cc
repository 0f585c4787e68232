// autocal_calibrate and autocal_fleet_report as a fleet's batch runs them (docs/fleet.md):
// stateless runs that each leave a result directory with status.yaml, also when they fail;
// several logs of one vehicle in one run; the gathered table and overview with its exit
// status.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <utility>
#include <vector>

#include "autocal/io/calibration_yaml.h"
#include "autocal/io/run_status.h"
#include "support/test_paths.h"
#include "support/tool_runner.h"

namespace autocal {
namespace {

namespace fs = std::filesystem;

std::string Problem() {
  return (fs::path(AUTOCAL_SOURCE_DIR) / "problems" / "imu_wheel_gnss.yaml").string();
}

// A 25 s urban log without the LiDAR of one vehicle (its right tyre `right_change_pct` %
// larger), simulated into `dir`.
void Simulate(const fs::path& dir, int seed, double right_change_pct = 0.0) {
  const test::ToolOutput run = test::RunTool(
      "autocal_simulate",
      "--scenario=urban --duration_s=25 --lidar=false --seed=" + std::to_string(seed) +
          " --right_wheel_radius_change_pct=" + std::to_string(right_change_pct) +
          " --out=" + dir.string());
  ASSERT_EQ(run.exit_code, 0) << run.text;
}

test::ToolOutput Calibrate(const std::string& datasets, const fs::path& out,
                           const std::string& extra = "") {
  return test::RunTool("autocal_calibrate", datasets + " --problem=" + Problem() + " --output=" +
                                                out.string() + " --progress=false " + extra);
}

std::string Read(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

TEST(FleetTools, RunsLeaveStatusAndTheReportGathersThem) {
  const fs::path root = test::OutputDir("fleet");
  Simulate(root / "log_a", 41);
  Simulate(root / "log_b", 42);
  Simulate(root / "log_c", 43, 1.0);
  fs::create_directories(root / "broken");
  std::ofstream(root / "broken" / "imu.csv") << "t_ns,gx,gy,gz,ax,ay,az\n1,2\n";
  fs::create_directories(root / "results");

  for (const char* log : {"log_a", "log_b", "log_c"}) {
    const test::ToolOutput run = Calibrate("--dataset=" + (root / log).string(),
                                           root / "results" / log, std::string("--vehicle=") + log);
    ASSERT_EQ(run.exit_code, 0) << run.text;
    const io::RunStatus status =
        io::ReadRunStatus((root / "results" / log / "status.yaml").string());
    EXPECT_EQ(status.exit_status, 0);
    EXPECT_EQ(status.vehicle, log);
    EXPECT_TRUE(fs::is_regular_file(root / "results" / log / "calibration.yaml"));
    // From the tool's start, as a failure's: reading the log counts, which the calibration's
    // own total leaves out.
    const std::string timings = Read(root / "results" / log / "timings.yaml");
    const size_t total = timings.find("seconds_total: ");
    ASSERT_NE(total, std::string::npos) << timings;
    EXPECT_GT(status.seconds, std::stod(timings.substr(total + 15))) << log;
  }
  // A failed run leaves status.yaml alone, with the message it printed.
  const fs::path failed = root / "results" / "broken";
  const test::ToolOutput run = Calibrate("--dataset=" + (root / "broken").string(), failed);
  EXPECT_EQ(run.exit_code, 1) << run.text;
  const io::RunStatus status = io::ReadRunStatus((failed / "status.yaml").string());
  EXPECT_EQ(status.exit_status, 1);
  EXPECT_EQ(status.vehicle, "broken");
  EXPECT_THAT(run.text, ::testing::HasSubstr(status.message));
  EXPECT_FALSE(fs::exists(failed / "calibration.yaml"));
  // Rerun into a failure's directory: the next result replaces it, and a failed run after
  // that leaves that result (with its own status.yaml) as it was.
  const fs::path rerun = root / "rerun";
  fs::remove_all(rerun);
  fs::copy(failed, rerun);
  EXPECT_EQ(Calibrate("--dataset=" + (root / "log_a").string(), rerun).exit_code, 0);
  const std::string result = Read(rerun / "calibration.yaml");
  ASSERT_FALSE(result.empty());
  const test::ToolOutput again = Calibrate("--dataset=" + (root / "broken").string(), rerun);
  EXPECT_EQ(again.exit_code, 1) << again.text;
  EXPECT_THAT(again.text, ::testing::HasSubstr("is kept as it was"));
  EXPECT_EQ(Read(rerun / "calibration.yaml"), result);
  EXPECT_EQ(io::ReadRunStatus((rerun / "status.yaml").string()).exit_status, 0);

  const fs::path report = root / "report";
  test::ToolOutput gathered =
      test::RunTool("autocal_fleet_report",
                    "--output=" + report.string() + " " + (root / "results" / "log_a").string() +
                        " " + (root / "results" / "log_b").string() + " " +
                        (root / "results" / "log_c").string() + " " + failed.string());
  EXPECT_EQ(gathered.exit_code, 2) << gathered.text;  // one run failed
  EXPECT_THAT(gathered.text, ::testing::HasSubstr("4 runs: 3 calibrated, 1 failed"));
  EXPECT_THAT(gathered.text, ::testing::HasSubstr("outlier: log_c: right rear wheel radius"));
  EXPECT_THAT(Read(report / "fleet.csv"), ::testing::HasSubstr("\"broken\""));
  EXPECT_THAT(Read(report / "fleet.html"), ::testing::HasSubstr("Failures"));
  // From a list file, the succeeded runs only: exit 0.
  std::ofstream(root / "results.txt") << "# the fleet\n"
                                      << (root / "results" / "log_a").string() << "\n\n"
                                      << (root / "results" / "log_b").string() << "\n";
  gathered = test::RunTool(
      "autocal_fleet_report",
      "--output=" + report.string() + " --results_file=" + (root / "results.txt").string());
  EXPECT_EQ(gathered.exit_code, 0) << gathered.text;
  // Bad input: exit 1, one line.
  gathered = test::RunTool("autocal_fleet_report", "--output=" + report.string());
  EXPECT_EQ(gathered.exit_code, 1);
  EXPECT_THAT(gathered.text, ::testing::HasSubstr("at least one result directory"));
}

// --dataset=DIR/ (as a shell completes it) labels the run after DIR, not with an empty name.
TEST(FleetTools, LabelsARunAfterADatasetGivenWithASlash) {
  const fs::path root = test::OutputDir("slash");
  fs::remove_all(root);
  fs::create_directories(root / "car_9");
  std::ofstream(root / "car_9" / "imu.csv") << "t_ns,gx,gy,gz,ax,ay,az\n";  // fails: no samples
  const test::ToolOutput run =
      Calibrate("--dataset=" + (root / "car_9").string() + "/", root / "result");
  EXPECT_EQ(run.exit_code, 1) << run.text;
  EXPECT_EQ(io::ReadRunStatus((root / "result" / "status.yaml").string()).vehicle, "car_9");
}

// --dataset in a --flagfile (repeated, as on the command line; a section for another
// program skipped, as gflags skips it) or from the environment (--fromenv) counts: the failed
// run's status.yaml lists the datasets it was given.
TEST(FleetTools, TakesDatasetsFromAFlagfileAndTheEnvironment) {
  const fs::path root = test::OutputDir("flagfile");
  fs::remove_all(root);
  for (const char* log : {"day1", "day2"}) {
    fs::create_directories(root / log);
    std::ofstream(root / log / "imu.csv") << "t_ns,gx,gy,gz,ax,ay,az\n";  // fails: no samples
  }
  std::ofstream(root / "flags.txt") << "# two logs\n--dataset=" << (root / "day1").string()
                                    << "\n  --dataset=" << (root / "day2").string()
                                    << "\nautocal_estimate\n--dataset=" << (root / "other").string()
                                    << "\nautocal_cal*\n--vehicle=car_5\n";
  test::ToolOutput run = Calibrate("--flagfile=" + (root / "flags.txt").string(), root / "result");
  EXPECT_EQ(run.exit_code, 1) << run.text;
  io::RunStatus status = io::ReadRunStatus((root / "result" / "status.yaml").string());
  EXPECT_THAT(status.datasets,
              ::testing::ElementsAre((root / "day1").string(), (root / "day2").string()));
  EXPECT_EQ(status.vehicle, "car_5");

  setenv("FLAGS_dataset", (root / "day2").string().c_str(), 1);
  run = Calibrate("--fromenv=dataset", root / "result");
  unsetenv("FLAGS_dataset");
  EXPECT_EQ(run.exit_code, 1) << run.text;
  status = io::ReadRunStatus((root / "result" / "status.yaml").string());
  EXPECT_THAT(status.datasets, ::testing::ElementsAre((root / "day2").string()));
}

// A report written into one of the result directories it gathers, around one or inside one
// would replace or bury that result: refused before anything is written.
TEST(FleetTools, RefusesAReportAmongItsResults) {
  const fs::path root = test::OutputDir("report_among_results");
  fs::remove_all(root);
  for (const char* vehicle : {"car_1", "car_2"}) {
    fs::create_directories(root / "results" / vehicle);
    io::RunStatus status;
    status.tool = "autocal_calibrate";
    status.vehicle = vehicle;
    status.exit_status = 1;
    status.message = "no GNSS";
    io::WriteRunStatus((root / "results" / vehicle / "status.yaml").string(), status);
  }
  const std::string results =
      (root / "results" / "car_1").string() + " " + (root / "results" / "car_2").string();
  const std::vector<std::pair<fs::path, std::string>> outputs = {
      {root / "results" / "car_1", "is the input"},
      {root / "results" / "car_2" / "", "is the input"},
      {root / "results" / "car_1" / "report", "lies inside the input"},
      {root / "results", "holds the input"}};
  for (const auto& [output, message] : outputs) {
    const test::ToolOutput run =
        test::RunTool("autocal_fleet_report", "--output=" + output.string() + " " + results);
    EXPECT_EQ(run.exit_code, 1) << run.text;
    EXPECT_THAT(run.text, ::testing::HasSubstr(message)) << output;
    EXPECT_EQ(io::ReadRunStatus((root / "results" / "car_1" / "status.yaml").string()).vehicle,
              "car_1");
    EXPECT_EQ(io::ReadRunStatus((root / "results" / "car_2" / "status.yaml").string()).vehicle,
              "car_2");
    EXPECT_FALSE(fs::exists(root / "results" / "car_1" / "fleet.csv"));
    EXPECT_FALSE(fs::exists(root / "results" / "car_1" / "report"));
  }
  const test::ToolOutput apart = test::RunTool(
      "autocal_fleet_report", "--output=" + (root / "report").string() + " " + results);
  EXPECT_EQ(apart.exit_code, 2) << apart.text;  // both runs failed; the report is written
  EXPECT_TRUE(fs::is_regular_file(root / "report" / "fleet.csv"));
}

// Two logs of one vehicle in one run (--dataset twice and a list file): the shared
// calibration, the repeatability table and each log's files.
TEST(FleetTools, CalibratesSeveralLogsOfOneVehicle) {
  const fs::path root = test::OutputDir("several");
  Simulate(root / "day1", 44);
  Simulate(root / "day2", 45);
  Simulate(root / "day3", 46);
  std::ofstream(root / "more.txt") << (root / "day3").string() << "\n";
  const fs::path out = root / "result";
  const test::ToolOutput run =
      Calibrate("--dataset=" + (root / "day1").string() + " --dataset " + (root / "day2").string() +
                    " --datasets_file=" + (root / "more.txt").string(),
                out, "--vehicle=car_1");
  ASSERT_EQ(run.exit_code, 0) << run.text;
  EXPECT_THAT(run.text, ::testing::HasSubstr("shared calibration of 3 logs"));
  EXPECT_TRUE(fs::is_regular_file(out / "calibration.yaml"));
  EXPECT_THAT(Read(out / "repeatability.csv"), ::testing::HasSubstr(",\"day2\","));
  for (const char* day : {"day1", "day2", "day3"}) {
    EXPECT_TRUE(fs::is_regular_file(out / "logs" / day / "trajectory.tum")) << day;
    EXPECT_TRUE(fs::is_regular_file(out / "logs" / day / "own" / "calibration.yaml")) << day;
    // --bound (default true): each simulated log's own report against its own truth.
    EXPECT_THAT(Read(out / "logs" / day / "own" / "report.html"),
                ::testing::HasSubstr("Against the Cramér–Rao bound"))
        << day;
  }
  const io::RunStatus status = io::ReadRunStatus((out / "status.yaml").string());
  EXPECT_EQ(status.datasets.size(), 3u);
  EXPECT_EQ(status.vehicle, "car_1");
  // A missing list file is refused before any work, and leaves the previous result.
  const test::ToolOutput bad = Calibrate("--datasets_file=" + (root / "absent.txt").string(), out);
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_THAT(bad.text, ::testing::HasSubstr("--datasets_file: cannot read"));
  EXPECT_EQ(io::ReadRunStatus((out / "status.yaml").string()).exit_status, 0);
}

}  // namespace
}  // namespace autocal
