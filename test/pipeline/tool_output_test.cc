// The command-line tools as a user runs them: a bad output location or dataset is refused
// before any work, and a run stopped with SIGKILL (no chance to clean up) leaves nothing that
// looks complete: no dataset, no result directory, the previous result untouched.

#include <fcntl.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "autocal/io/dataset.h"
#include "autocal/io/point_cloud_file.h"
#include "autocal/io/run_status.h"
#include "support/test_paths.h"

#ifndef AUTOCAL_TOOL_DIR
#error "test/CMakeLists.txt defines AUTOCAL_TOOL_DIR for this test"
#endif

namespace autocal {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

std::string Tool(const std::string& name) { return (fs::path(AUTOCAL_TOOL_DIR) / name).string(); }

std::string Read(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// Starts `args` (args[0] is the program) with stdout and stderr going to `log`.
pid_t StartTool(const std::vector<std::string>& args, const fs::path& log) {
  const pid_t pid = fork();
  if (pid == 0) {
    const int fd = open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    dup2(fd, 1);
    dup2(fd, 2);
    std::vector<char*> argv;
    for (const std::string& arg : args) argv.push_back(const_cast<char*>(arg.c_str()));
    argv.push_back(nullptr);
    execv(argv[0], argv.data());
    _exit(127);
  }
  return pid;
}

struct Finished {
  int exit_code = -1;  // -1 when killed by a signal
  double seconds = 0.0;
  std::string output;
};

Finished RunTool(const std::vector<std::string>& args, const fs::path& log) {
  const auto start = std::chrono::steady_clock::now();
  const pid_t pid = StartTool(args, log);
  int status = 0;
  waitpid(pid, &status, 0);
  Finished f;
  f.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  f.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  f.output = Read(log);
  return f;
}

// Kills the program with SIGKILL after `delay`; true when it was still running then.
bool KillAfter(pid_t pid, std::chrono::milliseconds delay) {
  std::this_thread::sleep_for(delay);
  const bool running = kill(pid, SIGKILL) == 0;
  int status = 0;
  waitpid(pid, &status, 0);
  return running && WIFSIGNALED(status);
}

// test::OutputDir(name), emptied: a test's earlier run leaves nothing behind.
fs::path CleanDir(const std::string& name) {
  const fs::path dir = test::OutputDir(name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// Entries of `directory` whose names start with `prefix`.
std::vector<std::string> Named(const fs::path& directory, const std::string& prefix) {
  std::vector<std::string> names;
  for (const auto& entry : fs::directory_iterator(directory)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind(prefix, 0) == 0) names.push_back(name);
  }
  return names;
}

// `dir` is absent, or holds only the status.yaml of a failed run (docs/fleet.md): nothing
// that looks like a result.
void ExpectNoResult(const fs::path& dir) {
  if (!fs::exists(dir)) return;
  for (const fs::directory_entry& entry : fs::directory_iterator(dir)) {
    EXPECT_EQ(entry.path().filename(), "status.yaml") << entry.path();
  }
  EXPECT_EQ(io::ReadRunStatus((dir / "status.yaml").string()).exit_status, 1);
}

// A 24 s urban drive (16 beams, seed 7) simulated by autocal_simulate into dir/drive.
fs::path SimulateShortDrive(const fs::path& dir) {
  const fs::path dataset = dir / "drive";
  const Finished sim = RunTool({Tool("autocal_simulate"), "--duration_s=24", "--lidar_beams=16",
                                "--seed=7", "--out=" + dataset.string()},
                               dir / "log.txt");
  EXPECT_EQ(sim.exit_code, 0) << sim.output;
  return dataset;
}

class ToolOutputTest : public ::testing::Test {
 protected:
  void SetUp() override {
    for (const char* tool : {"autocal_simulate", "autocal_calibrate", "autocal_estimate"}) {
      ASSERT_TRUE(fs::exists(Tool(tool))) << Tool(tool) << " is not built";
    }
  }
};

// Each refusal takes well under a second (the solve it used to follow took 79-104 s) and is
// one line.
TEST_F(ToolOutputTest, ABadOutputOrDatasetIsRefusedBeforeAnyWork) {
  const fs::path dir = CleanDir("refusals");
  std::ofstream(dir / "a_file") << "x";
  fs::create_directories(dir / "empty");
  fs::create_directories(dir / "no_imu");
  std::ofstream(dir / "no_imu" / "notes.txt") << "x";
  const std::string problem = std::string(AUTOCAL_SOURCE_DIR) + "/problems/urban_full.yaml";
  struct Case {
    std::vector<std::string> args;
    std::string message;
  };
  const std::vector<Case> cases = {
      {{Tool("autocal_calibrate"), "--dataset=" + (dir / "empty").string(), "--problem=" + problem,
        "--output=" + (dir / "a_file").string()},
       "it exists and is not a directory"},
      {{Tool("autocal_calibrate"), "--dataset=" + (dir / "empty").string(), "--problem=" + problem,
        "--output=" + (dir / "r").string()},
       "is an empty directory, not a dataset"},
      {{Tool("autocal_estimate"), "--dataset=" + (dir / "a_file").string(), "--problem=" + problem,
        "--output=" + (dir / "missing" / "r").string()},
       "/missing' does not exist"},
      {{Tool("autocal_estimate"), "--dataset=" + (dir / "no_imu").string(), "--problem=" + problem,
        "--output=" + (dir / "r").string()},
       "is not a dataset: it has no imu.csv"},
      {{Tool("autocal_calibrate"), "--dataset=" + (dir / "no_imu").string(), "--problem=" + problem,
        "--output=" + (dir / "r").string(), "--threads=0"},
       "is not a dataset"},
      {{Tool("autocal_simulate"), "--duration_s=600", "--out=" + (dir / "a_file").string()},
       "it exists and is not a directory"},
      {{Tool("autocal_simulate"), "--duration_s=600", "--out=" + dir.string()},
       "which is not part of an autocal dataset"},
      {{Tool("autocal_register"), "--source=s.ply", "--target=t.ply", "--output=" + dir.string()},
       "it is a directory"},
      {{Tool("autocal_simulate"), "--wheel_form=rates", "--out=" + (dir / "w").string()},
       "--wheel_form must be angular_rates, linear_speeds or speed_yaw_rate, got 'rates'"},
      {{Tool("autocal_simulate"), "--imu_random_walk_scale=nan", "--out=" + (dir / "w").string()},
       "--imu_random_walk_scale must be a number (negative: --imu_noise_scale), got nan"},
      {{Tool("autocal_simulate"), "--origin_alt_m=1e30", "--out=" + (dir / "w").string()},
       "gnss origin_alt_m must be in [-1000, 100000] m, got 1e+30"},
  };
  for (const Case& c : cases) {
    const Finished f = RunTool(c.args, dir / "log.txt");
    EXPECT_EQ(f.exit_code, 1) << c.args[0] << ": " << f.output;
    EXPECT_THAT(f.output, HasSubstr(c.message)) << c.args[0];
    EXPECT_LT(f.seconds, 5.0) << c.args[0];
    EXPECT_EQ(std::count(f.output.begin(), f.output.end(), '\n'), 1) << "one line: " << f.output;
  }
  ExpectNoResult(dir / "r");
  EXPECT_FALSE(fs::exists(dir / "w"));
}

// A mistyped --problem or --dataset is an error of the command, not of the run: the previous
// result in --output stays as it was (it used to be replaced by a failure's status.yaml). So
// does a dataset that fails once it is read (a wrong header, no samples): bad input loses
// nothing, and the failure says the previous result was kept.
TEST_F(ToolOutputTest, AWrongInputLeavesThePreviousResult) {
  const fs::path dir = CleanDir("wrong_input");
  const fs::path data = dir / "data";  // a dataset apart from the output
  fs::create_directories(data);
  std::ofstream(data / "imu.csv") << "t_ns,gx,gy,gz,ax,ay,az\n";
  fs::create_directories(dir / "bad");
  std::ofstream(dir / "bad" / "imu.csv") << "garbage,gx\n1,2\n";
  const fs::path result = dir / "result";
  fs::create_directories(result);
  std::ofstream(result / "calibration.yaml") << "previous\n";
  const std::string problem = std::string(AUTOCAL_SOURCE_DIR) + "/problems/urban_full.yaml";
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"--dataset=" + data.string(), "--problem=" + problem + "x"}, "urban_full.yamlx"},
      {{"--dataset=" + (dir / "typo").string(), "--problem=" + problem}, "typo' does not exist"},
      {{"--dataset=" + data.string(), "--dataset=" + (dir / "typo").string(),
        "--problem=" + problem},
       "typo' does not exist"},
      {{"--dataset=" + (dir / "bad").string(), "--problem=" + problem},
       "header column 1 is 'garbage'"},
      {{"--dataset=" + data.string(), "--problem=" + problem}, "no IMU samples after the header"},
      {{"--dataset=" + (dir / "bad").string(), "--dataset=" + data.string(),
        "--problem=" + problem},
       "header column 1 is 'garbage'"}};
  for (const auto& [args, message] : cases) {
    std::vector<std::string> command = {Tool("autocal_calibrate"), "--output=" + result.string()};
    command.insert(command.end(), args.begin(), args.end());
    const Finished f = RunTool(command, dir / "log.txt");
    EXPECT_EQ(f.exit_code, 1) << f.output;
    EXPECT_THAT(f.output, HasSubstr(message));
    EXPECT_EQ(Read(result / "calibration.yaml"), "previous\n") << message;
    EXPECT_FALSE(fs::exists(result / "status.yaml")) << message;
  }
  const Finished f = RunTool({Tool("autocal_calibrate"), "--output=" + result.string(),
                              "--dataset=" + (dir / "bad").string(), "--problem=" + problem},
                             dir / "log.txt");
  EXPECT_THAT(f.output, HasSubstr("the previous result in '" + result.string() +
                                  "' is kept as it was; this failure is not recorded there"));
}

// An --output that holds an input (a dataset kept under logs/, which a result may hold, or
// the problem file) would be replaced with it, by the result or by a failed run's
// status.yaml; one inside a dataset would put the result among the recordings. Both are
// refused in one line before any work, however the paths are spelled (a symbolic link, a
// trailing slash, '..'), and every input stays as it was.
TEST_F(ToolOutputTest, AnOutputAroundAnInputIsRefused) {
  const fs::path base = CleanDir("around_input");
  const fs::path d = base / "d", day = d / "logs" / "day1", other = base / "other";
  const std::string imu = "t_ns,gx,gy,gz,ax,ay,az\n";
  for (const fs::path& dataset : {day, other}) {
    fs::create_directories(dataset);
    std::ofstream(dataset / "imu.csv") << imu;
  }
  const std::string shipped = std::string(AUTOCAL_SOURCE_DIR) + "/problems/urban_full.yaml";
  const fs::path problem = d / "logs" / "problem.yaml";
  fs::copy_file(shipped, problem);
  const std::string link = (base / "link").string();  // another name of d
  fs::create_directory_symlink(d, link);
  struct Case {
    std::vector<std::string> args;
    std::string message;
  };
  const std::string holds = "' holds the input '";
  const std::vector<Case> cases = {
      {{Tool("autocal_calibrate"), "--dataset=" + day.string(), "--problem=" + shipped,
        "--output=" + d.string()},
       holds + day.string() + "'"},
      {{Tool("autocal_calibrate"), "--dataset=" + other.string(), "--dataset=" + day.string(),
        "--problem=" + shipped, "--output=" + link + "/"},
       holds + day.string() + "'"},
      {{Tool("autocal_calibrate"), "--dataset=" + other.string(), "--problem=" + problem.string(),
        "--output=" + (day / ".." / "..").string()},
       holds + problem.string() + "'"},
      {{Tool("autocal_calibrate"), "--dataset=" + day.string(), "--problem=" + shipped,
        "--output=" + (day / "result").string()},
       "' lies inside the input '" + day.string() + "'"},
      {{Tool("autocal_estimate"), "--dataset=" + day.string(), "--problem=" + shipped,
        "--output=" + link},
       holds + day.string() + "'"},
      {{Tool("autocal_estimate"), "--dataset=" + other.string(), "--problem=" + problem.string(),
        "--output=" + (d / "logs").string()},
       holds + problem.string() + "'"},
  };
  for (const Case& c : cases) {
    const Finished f = RunTool(c.args, base / "log.txt");
    EXPECT_EQ(f.exit_code, 1) << c.args[0] << ": " << f.output;
    EXPECT_THAT(f.output, HasSubstr("--output: '")) << c.args[0];
    EXPECT_THAT(f.output, HasSubstr(c.message)) << c.args[0];
    EXPECT_EQ(std::count(f.output.begin(), f.output.end(), '\n'), 1) << "one line: " << f.output;
    EXPECT_EQ(Read(day / "imu.csv"), imu) << c.args.back();
    EXPECT_EQ(Read(other / "imu.csv"), imu) << c.args.back();
    EXPECT_EQ(Read(problem), Read(shipped)) << c.args.back();
    EXPECT_FALSE(fs::exists(d / "status.yaml")) << c.args.back();
    EXPECT_FALSE(fs::exists(day / "result")) << c.args.back();
  }
}

// autocal_register on the real scan pair: started at the reference 4x4 (--init=FILE) it
// converges (exit 0, the file written); stopped after one iteration from the identity it is
// not converged: exit 2, the report printed, no file written.
TEST_F(ToolOutputTest, RegisterStartsFromAGuessAndSaysWhenItDidNotConverge) {
  const fs::path pair = test::SharedDataDir("lidar_scan_pair");
  AUTOCAL_REQUIRE_SHARED_DATA(pair / "source.ply");
  const fs::path dir = CleanDir("register");
  const std::vector<std::string> clouds = {Tool("autocal_register"),
                                           "--source=" + (pair / "source.ply").string(),
                                           "--target=" + (pair / "target.ply").string()};
  std::vector<std::string> from_guess = clouds;
  from_guess.push_back("--init=" + (pair / "T_target_source.txt").string());
  from_guess.push_back("--num_threads=2");
  from_guess.push_back("--output=" + (dir / "guess.yaml").string());
  const Finished converged = RunTool(from_guess, dir / "log.txt");
  EXPECT_EQ(converged.exit_code, 0) << converged.output;
  EXPECT_TRUE(fs::exists(dir / "guess.yaml"));

  std::vector<std::string> one_step = clouds;
  one_step.push_back("--max_iterations=1");
  one_step.push_back("--output=" + (dir / "one.yaml").string());
  const Finished stopped = RunTool(one_step, dir / "log.txt");
  EXPECT_EQ(stopped.exit_code, 2) << stopped.output;
  EXPECT_THAT(stopped.output, HasSubstr("not converged within 1 iterations"));
  EXPECT_THAT(stopped.output, HasSubstr("T_target_source"));
  EXPECT_FALSE(fs::exists(dir / "one.yaml"));

  std::vector<std::string> bad = clouds;
  bad.push_back("--init=1,2,3");
  const Finished refused = RunTool(bad, dir / "log.txt");
  EXPECT_EQ(refused.exit_code, 1);
  EXPECT_THAT(refused.output, HasSubstr("--init: expected 6 numbers"));
}

// A corner of three walls, 2 m on a side, sampled every 0.1 m: a cloud ICP aligns to itself.
void WriteCorner(const fs::path& path) {
  lidar::PointCloud cloud;
  cloud.points.resize(3, 3 * 20 * 20);
  int n = 0;
  for (int i = 0; i < 20; ++i) {
    for (int j = 0; j < 20; ++j) {
      const double a = 0.1 * i, b = 0.1 * j;
      cloud.points.col(n++) = Eigen::Vector3d(a, b, 0.0);
      cloud.points.col(n++) = Eigen::Vector3d(a, 0.0, b);
      cloud.points.col(n++) = Eigen::Vector3d(0.0, a, b);
    }
  }
  io::WritePly(path.string(), cloud);
}

// autocal_register --output naming one of its inputs (the clouds, the --init file) would
// replace that input by the result: refused before the registration, the input kept.
TEST_F(ToolOutputTest, RegisterKeepsItsInputs) {
  const fs::path dir = CleanDir("register_inputs");
  WriteCorner(dir / "source.ply");
  WriteCorner(dir / "target.ply");
  std::ofstream(dir / "init.txt") << "1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n";
  const std::string cloud = Read(dir / "source.ply"), init = Read(dir / "init.txt");
  const std::vector<std::string> inputs = {
      Tool("autocal_register"), "--source=" + (dir / "source.ply").string(),
      "--target=" + (dir / "target.ply").string(), "--init=" + (dir / "init.txt").string()};
  for (const auto& [output, flag] : std::vector<std::pair<fs::path, std::string>>{
           {dir / "source.ply", "--source"},
           {dir / "sub" / ".." / "target.ply", "--target"},
           {dir / "init.txt", "--init"}}) {
    fs::create_directories(dir / "sub");
    std::vector<std::string> args = inputs;
    args.push_back("--output=" + output.string());
    const Finished f = RunTool(args, dir / "log.txt");
    EXPECT_EQ(f.exit_code, 1) << f.output;
    EXPECT_THAT(f.output, HasSubstr("is the file " + flag + " reads"));
  }
  EXPECT_EQ(Read(dir / "source.ply"), cloud);
  EXPECT_EQ(Read(dir / "target.ply"), cloud);
  EXPECT_EQ(Read(dir / "init.txt"), init);
  std::vector<std::string> apart = inputs;
  apart.push_back("--output=" + (dir / "result.yaml").string());
  const Finished f = RunTool(apart, dir / "log.txt");
  EXPECT_EQ(f.exit_code, 0) << f.output;
  EXPECT_TRUE(fs::is_regular_file(dir / "result.yaml"));
}

// --threads is recognized by both solving tools: a value out of range is refused naming the
// problem file's key it replaces, a valid one passes on to the dataset (here a bare imu.csv
// header, refused by the reader).
TEST_F(ToolOutputTest, ThreadsIsAnOverrideOfTheProblemFile) {
  const fs::path dir = CleanDir("threads");
  const std::string data = (dir / "data").string();  // a dataset apart from the output
  fs::create_directories(data);
  std::ofstream(data + "/imu.csv") << "t_ns,gx,gy,gz,ax,ay,az\n";
  const std::string problem = std::string(AUTOCAL_SOURCE_DIR) + "/problems/urban_full.yaml";
  for (const char* tool : {"autocal_calibrate", "autocal_estimate"}) {
    const Finished bad = RunTool({Tool(tool), "--dataset=" + data, "--problem=" + problem,
                                  "--output=" + (dir / "r").string(), "--threads=-1"},
                                 dir / "log.txt");
    EXPECT_EQ(bad.exit_code, 1) << tool;
    EXPECT_THAT(bad.output, HasSubstr("--threads must be 0 (the problem file's "
                                      "solver.num_threads) or 1..1024, got -1"))
        << tool;
    const Finished good = RunTool({Tool(tool), "--dataset=" + data, "--problem=" + problem,
                                   "--output=" + (dir / "r").string(), "--threads=3"},
                                  dir / "log.txt");
    EXPECT_EQ(good.exit_code, 1) << tool;
    EXPECT_THAT(good.output, HasSubstr("no IMU samples after the header")) << tool;
    EXPECT_THAT(good.output, ::testing::Not(HasSubstr("--threads"))) << tool;
  }
  ExpectNoResult(dir / "r");
}

// --scatter_stretches (Eqs. C8, W9) is checked before any work: too few stretches to compare,
// or more than 1000 (a sensor with fewer rows than stretches goes untested without a word),
// are refused in one line; 0 (no test) passes on to the dataset.
TEST_F(ToolOutputTest, ScatterStretchesIsCheckedBeforeAnyWork) {
  const fs::path dir = CleanDir("scatter");
  const std::string data = (dir / "data").string();  // a dataset apart from the output
  fs::create_directories(data);
  std::ofstream(data + "/imu.csv") << "t_ns,gx,gy,gz,ax,ay,az\n";
  const std::string problem = std::string(AUTOCAL_SOURCE_DIR) + "/problems/urban_full.yaml";
  for (const auto& [tool, least] : std::vector<std::pair<std::string, int>>{
           {"autocal_calibrate", 2}, {"autocal_estimate", 3}}) {
    for (const int stretches : {least - 1, 1001, 1000000}) {
      const Finished bad = RunTool(
          {Tool(tool), "--dataset=" + data, "--problem=" + problem,
           "--output=" + (dir / "r").string(), "--scatter_stretches=" + std::to_string(stretches)},
          dir / "log.txt");
      EXPECT_EQ(bad.exit_code, 1) << tool;
      EXPECT_THAT(bad.output,
                  HasSubstr("--scatter_stretches must be 0 (no test) or " + std::to_string(least) +
                            "..1000, got " + std::to_string(stretches)))
          << tool;
    }
    const Finished off = RunTool({Tool(tool), "--dataset=" + data, "--problem=" + problem,
                                  "--output=" + (dir / "r").string(), "--scatter_stretches=0"},
                                 dir / "log.txt");
    EXPECT_EQ(off.exit_code, 1) << tool;
    EXPECT_THAT(off.output, HasSubstr("no IMU samples after the header")) << tool;
  }
  ExpectNoResult(dir / "r");
}

// autocal_estimate checks its initialization flags before it reads the dataset: a duration
// of 1e300 s overflowed int64 nanoseconds and was reported as an initialization over 0 sweeps.
TEST_F(ToolOutputTest, EstimateChecksTheInitializationFlagsFirst) {
  const fs::path dir = CleanDir("init_flags");
  std::ofstream(dir / "imu.csv") << "t_ns,gx,gy,gz,ax,ay,az\n";
  const std::string problem = std::string(AUTOCAL_SOURCE_DIR) + "/problems/urban_full.yaml";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"--init_duration_s=1e300",
       "--init_duration_s must be a positive number of seconds up to 1e9, got 1e+300"},
      {"--init_duration_s=inf", "--init_duration_s must be a positive number of seconds"},
      {"--init_duration_s=nan", "--init_duration_s must be a positive number of seconds"},
      {"--init_duration_s=0", "--init_duration_s must be a positive number of seconds"},
      {"--init_sweep_stride=0", "--init_sweep_stride must be at least 1, got 0"}};
  for (const auto& [flag, message] : cases) {
    const Finished f = RunTool({Tool("autocal_estimate"), "--dataset=" + dir.string(),
                                "--problem=" + problem, "--output=" + (dir / "r").string(), flag},
                               dir / "log.txt");
    EXPECT_EQ(f.exit_code, 1) << flag;
    EXPECT_THAT(f.output, HasSubstr(message)) << flag;
  }
  ExpectNoResult(dir / "r");
}

// autocal_estimate ends with the final values as autocal_calibrate prints them: each estimated
// block's value, sigma and observability per direction, with and without the LiDAR.
TEST_F(ToolOutputTest, EstimatePrintsSigmaAndObservabilityAsTheBatchDoes) {
  const fs::path dir = CleanDir("estimate_summary");
  const fs::path dataset = SimulateShortDrive(dir);
  struct Case {
    std::string problem;
    std::vector<std::string> lines;  // each printed with "sigma" and "observable"
  };
  const std::vector<Case> cases = {
      {"urban_full.yaml",
       {"T_I_L roll pitch yaw (deg)", "T_I_L translation (mm)", "time offset lidar->imu (ms)",
        "IMU mount roll pitch yaw (deg)", "GNSS lever arm p_I_A (mm)"}},
      {"imu_wheel_gnss.yaml",
       {"left rear wheel radius (mm)", "IMU mount roll pitch yaw (deg)",
        "GNSS lever arm p_I_A (mm)"}}};
  for (const Case& c : cases) {
    const fs::path result = dir / ("result_" + c.problem);
    const Finished f =
        RunTool({Tool("autocal_estimate"), "--dataset=" + dataset.string(),
                 "--problem=" + std::string(AUTOCAL_SOURCE_DIR) + "/problems/" + c.problem,
                 "--output=" + result.string(), "--init_duration_s=10", "--progress_every=0"},
                dir / "log.txt");
    ASSERT_EQ(f.exit_code, 0) << c.problem << ": " << f.output;
    for (const std::string& name : c.lines) {
      const size_t at = f.output.find("\n" + name);
      ASSERT_NE(at, std::string::npos) << c.problem << " prints no " << name << ":\n" << f.output;
      const std::string line = f.output.substr(at + 1, f.output.find('\n', at + 1) - at - 1);
      EXPECT_THAT(line, HasSubstr("   sigma ")) << line;
      EXPECT_THAT(line, ::testing::ContainsRegex("observable( (yes|no))+$")) << line;
    }
    EXPECT_EQ(f.output.find("T_I_L") == std::string::npos, c.problem == "imu_wheel_gnss.yaml")
        << f.output;
  }
}

// A simulation stopped while it writes sweeps leaves only OUT.partial-XXXXXX; one that runs
// to the end leaves the whole dataset and no staging directory.
TEST_F(ToolOutputTest, AStoppedSimulationLeavesNoDataset) {
  const fs::path dir = CleanDir("simulate");
  const fs::path out = dir / "drive";
  // 64 beams for 600 s: minutes of sweeps, killed once it has written a few.
  const pid_t pid = StartTool(
      {Tool("autocal_simulate"), "--duration_s=600", "--lidar_beams=64", "--out=" + out.string()},
      dir / "log.txt");
  const auto sweeps_written = [&] {
    for (const std::string& name : Named(dir, "drive.partial-")) {
      std::error_code error;
      const fs::path lidar = dir / name / "lidar";
      if (fs::is_directory(lidar, error) &&
          std::distance(fs::directory_iterator(lidar, error), fs::directory_iterator()) >= 3) {
        return true;
      }
    }
    return false;
  };
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (!sweeps_written() && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ASSERT_TRUE(sweeps_written()) << "no sweep written within 60 s";
  ASSERT_TRUE(KillAfter(pid, std::chrono::milliseconds(0))) << "finished before the kill";
  EXPECT_FALSE(fs::exists(out));
  ASSERT_EQ(Named(dir, "drive.partial-").size(), 1u);

  const Finished f = RunTool(
      {Tool("autocal_simulate"), "--duration_s=3", "--lidar_beams=16", "--out=" + out.string()},
      dir / "log.txt");
  ASSERT_EQ(f.exit_code, 0) << f.output;
  EXPECT_NO_THROW(io::ReadDataset(out.string()));
  EXPECT_EQ(Named(dir, "drive.partial-").size(), 1u);  // the stopped run's, nothing new
}

// A preset's stamp jitter is a share of its sample period: another rate given alone keeps the
// share (the skid-steer robot's 2 ms at 30 Hz is 0.3 ms at 200 Hz) instead of being refused as
// 0.4 periods, and the dataset states the jitter it was simulated with.
TEST_F(ToolOutputTest, APresetAtAnotherRateKeepsItsJitterShare) {
  const fs::path dir = CleanDir("preset_rate");
  const fs::path out = dir / "robot";
  const Finished f = RunTool({Tool("autocal_simulate"), "--preset=skid_steer", "--imu_rate_hz=200",
                              "--duration_s=3", "--out=" + out.string()},
                             dir / "log.txt");
  ASSERT_EQ(f.exit_code, 0) << f.output;
  const YAML::Node timing = YAML::LoadFile((out / "groundtruth" / "timing.yaml").string());
  EXPECT_DOUBLE_EQ(timing["imu"]["rate_hz"].as<double>(), 200.0);
  EXPECT_NEAR(timing["imu"]["stamp_jitter_s"].as<double>(), 0.002 * 30.0 / 200.0, 1e-12);
  EXPECT_NO_THROW(io::ReadDataset(out.string()));
}

// autocal_evaluate names a result directory that is not there (exit 2, bad input) instead of
// failing to write evaluation.yaml into it.
TEST_F(ToolOutputTest, EvaluateNamesAMissingResult) {
  const fs::path dir = CleanDir("evaluate_missing");
  const Finished f = RunTool({Tool("autocal_evaluate"), "--dataset=" + dir.string(),
                              "--result=" + (dir / "none").string()},
                             dir / "log.txt");
  EXPECT_EQ(f.exit_code, 2) << f.output;
  EXPECT_THAT(f.output, HasSubstr("--result: '" + (dir / "none").string() +
                                  "' does not exist or is not a directory"));
}

// A calibration stopped midway leaves the previous result as it was.
TEST_F(ToolOutputTest, AStoppedCalibrationLeavesThePreviousResult) {
  const fs::path dir = CleanDir("calibrate");
  const fs::path dataset = SimulateShortDrive(dir);
  const fs::path result = dir / "result";
  fs::create_directories(result);
  std::ofstream(result / "calibration.yaml") << "previous\n";
  const std::string problem = std::string(AUTOCAL_SOURCE_DIR) + "/problems/urban_full.yaml";
  for (const char* tool : {"autocal_calibrate", "autocal_estimate"}) {
    const pid_t pid = StartTool({Tool(tool), "--dataset=" + dataset.string(),
                                 "--problem=" + problem, "--output=" + result.string()},
                                dir / "log.txt");
    ASSERT_TRUE(KillAfter(pid, std::chrono::milliseconds(2000))) << tool << " finished first";
    EXPECT_EQ(Read(result / "calibration.yaml"), "previous\n") << tool;
    EXPECT_FALSE(fs::exists(result / "trajectory.tum")) << tool;
  }
}

}  // namespace
}  // namespace autocal
