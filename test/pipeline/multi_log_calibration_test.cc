// Several logs of one vehicle (pipeline/multi_log_calibration.h): three simulated urban drives
// without the LiDAR, one vehicle (one true calibration), seeds no other test uses. The shared
// calibration knows more than any log, covers the truth, and the repeatability test agrees
// on them; a right rear tyre 0.4 % larger in one log is found and named.

#include "autocal/pipeline/multi_log_calibration.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <sstream>

#include "autocal/common/error.h"
#include "autocal/evaluation/information_bound.h"
#include "autocal/io/calibration_yaml.h"
#include "autocal/io/dataset.h"
#include "autocal/io/problem_yaml.h"
#include "autocal/pipeline/fleet_report.h"
#include "autocal/sensors/calibration_blocks.h"
#include "pipeline/multi_log_report.h"
#include "pipeline/simulated_urban_dataset.h"
#include "support/test_paths.h"

namespace autocal {
namespace pipeline {
namespace {

io::Problem ImuWheelGnssProblem() { return test::ShippedProblem("imu_wheel_gnss.yaml"); }

// Urban drive `seed`, 30 s, no LiDAR; the right rear tyre `right_change_pct` % larger.
std::unique_ptr<test::SimulatedUrbanDataset> Log(uint64_t seed, double right_change_pct = 0.0) {
  sim::SimulationOptions options = test::UrbanDriveOptions(30.0);
  options.seed = seed;
  options.lidar.enabled = false;
  options.true_calibration.wheel_radius_right_m *= 1.0 + right_change_pct / 100.0;
  return std::make_unique<test::SimulatedUrbanDataset>(options, "multi_log");
}

// The logs read as datasets.
std::vector<io::Dataset> Read(
    const std::vector<std::unique_ptr<test::SimulatedUrbanDataset>>& logs) {
  std::vector<io::Dataset> datasets;
  for (const auto& log : logs) datasets.push_back(io::ReadDataset(log->directory));
  return datasets;
}

class MultiLogCalibration : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    for (uint64_t seed : {31, 32, 33}) logs_.push_back(Log(seed));
    result_ = new MultiLogCalibrationResult(CalibrateDatasets(Read(logs_), ImuWheelGnssProblem()));
    std::cout << FormatMultiLogSummary(*result_);
  }
  static void TearDownTestSuite() {
    delete result_;
    logs_.clear();
  }
  static std::vector<std::unique_ptr<test::SimulatedUrbanDataset>> logs_;
  static MultiLogCalibrationResult* result_;
};
std::vector<std::unique_ptr<test::SimulatedUrbanDataset>> MultiLogCalibration::logs_;
MultiLogCalibrationResult* MultiLogCalibration::result_ = nullptr;

// Each observed scalar: the shared sigma below every log's own, the shared value within 3
// sigma of the truth.
TEST_F(MultiLogCalibration, SharedCalibrationKnowsMoreAndCoversTheTruth) {
  const sensors::Calibration& truth = logs_[0]->simulator.true_calibration();
  const sensors::Calibration& shared = result_->calibration.value;
  const io::CalibrationUncertainty& u = result_->calibration.uncertainty;
  struct Scalar {
    const char* name;
    double shared, truth;
    const io::ScalarBlockInfo& (*own)(const io::CalibrationUncertainty&);
    const io::ScalarBlockInfo& info;
  };
  const std::vector<Scalar> scalars = {
      {"left radius", shared.wheel_radius_left_m, truth.wheel_radius_left_m,
       [](const io::CalibrationUncertainty& o) -> const io::ScalarBlockInfo& {
         return o.wheel_radius_left_m;
       },
       u.wheel_radius_left_m},
      {"right radius", shared.wheel_radius_right_m, truth.wheel_radius_right_m,
       [](const io::CalibrationUncertainty& o) -> const io::ScalarBlockInfo& {
         return o.wheel_radius_right_m;
       },
       u.wheel_radius_right_m},
      {"track width", shared.track_width_m, truth.track_width_m,
       [](const io::CalibrationUncertainty& o) -> const io::ScalarBlockInfo& {
         return o.track_width_m;
       },
       u.track_width_m}};
  for (const Scalar& s : scalars) {
    ASSERT_TRUE(s.info.sigma) << s.name;
    std::cout << s.name << ": shared " << s.shared << " truth " << s.truth << " sigma "
              << *s.info.sigma << '\n';
    EXPECT_LE(std::abs(s.shared - s.truth), 3.0 * *s.info.sigma) << s.name;
    for (const LogCalibration& log : result_->logs) {
      ASSERT_TRUE(s.own(log.own.calibration.uncertainty).sigma) << s.name;
      EXPECT_LT(*s.info.sigma, *s.own(log.own.calibration.uncertainty).sigma) << s.name;
    }
  }
  // Three logs of the radius's information: its sigma near 1/sqrt(3) of one log's.
  const double own = *result_->logs[0].own.calibration.uncertainty.wheel_radius_left_m.sigma;
  EXPECT_LT(*u.wheel_radius_left_m.sigma, 0.75 * own);
}

TEST_F(MultiLogCalibration, LogsOfOneVehicleAgree) {
  ASSERT_FALSE(result_->repeatability.empty());
  for (const BlockRepeatability& r : result_->repeatability) {
    EXPECT_TRUE(r.agree) << r.name << " p " << r.agreement.p_value;
    EXPECT_TRUE(r.finding.empty());
    EXPECT_EQ(r.agreement.logs.size(), 3u);
  }
}

// Each log's trajectory is solved at the shared calibration, with every keyframe of its own
// solve.
TEST_F(MultiLogCalibration, TrajectoriesFollowTheSharedCalibration) {
  ASSERT_EQ(result_->logs.size(), 3u);
  for (const LogCalibration& log : result_->logs) {
    EXPECT_EQ(log.at_shared.calibration.value.wheel_radius_left_m,
              result_->calibration.value.wheel_radius_left_m);
    EXPECT_TRUE(log.at_shared.calibration.value.p_I_A.isApprox(result_->calibration.value.p_I_A));
    EXPECT_EQ(log.at_shared.trajectory.size(), log.own.trajectory.size());
    EXPECT_TRUE(log.at_shared.posterior.blocks.empty());  // nothing estimated
  }
}

TEST_F(MultiLogCalibration, WritesSharedRepeatabilityAndEveryLog) {
  const std::filesystem::path out = test::OutputDir("multi_log") / "result";
  std::filesystem::remove_all(out);
  WriteMultiLogResult(out.string(), *result_);
  const io::CalibrationFile read = io::ReadCalibrationYaml((out / "calibration.yaml").string());
  EXPECT_EQ(read.value.wheel_radius_right_m, result_->calibration.value.wheel_radius_right_m);
  std::ifstream csv(out / "repeatability.csv");
  std::string header;
  std::getline(csv, header);
  EXPECT_EQ(header,
            "block,direction,unit,log,value,sigma,chi_square,degrees_of_freedom,p_value,agree");
  int rows = 0;
  for (std::string line; std::getline(csv, line);) ++rows;
  int directions = 0;
  for (const BlockRepeatability& r : result_->repeatability) {
    directions += sensors::CalibrationBlock(r.agreement.id).tangent_size;
  }
  EXPECT_EQ(rows, directions * 4);  // three logs and the shared value
  // The shared rows give calibration.yaml's sigmas (after holding, Eq. C2): the fused ones
  // from before holding were shown beside the held values.
  const std::map<std::string, std::optional<double>> reported = {
      {"wheel_radius_left_m", read.uncertainty.wheel_radius_left_m.sigma},
      {"wheel_radius_right_m", read.uncertainty.wheel_radius_right_m.sigma},
      {"track_width_m", read.uncertainty.track_width_m.sigma},
      {"time_offset_wheel_imu_s", read.uncertainty.time_offset_wheel_imu_s.sigma}};
  int compared = 0;
  for (const RepeatabilityRow& row : RepeatabilityRows(*result_)) {
    const auto it = reported.find(row.key);
    if (it == reported.end() || !it->second) continue;
    const double scale = sensors::CalibrationBlock(row.block->agreement.id).display_scale;
    EXPECT_NEAR(row.shared.sigma, *it->second * scale, 1e-9 * row.shared.sigma) << row.key;
    ++compared;
  }
  EXPECT_GT(compared, 0);
  for (const LogCalibration& log : result_->logs) {
    EXPECT_TRUE(std::filesystem::is_regular_file(out / "logs" / log.name / "trajectory.tum"));
    EXPECT_TRUE(
        std::filesystem::is_regular_file(out / "logs" / log.name / "own" / "calibration.yaml"));
    EXPECT_TRUE(std::filesystem::is_regular_file(out / "logs" / log.name / "own" / "report.html"));
  }
  std::ifstream html(out / "report.html");
  std::stringstream text;
  text << html.rdbuf();
  EXPECT_THAT(text.str(), ::testing::HasSubstr("<h2>Repeatability</h2>"));
  EXPECT_THAT(text.str(), ::testing::HasSubstr("</html>"));
}

// Each log's own calibration (without the LiDAR) records its stages' times: Ceres' share of
// the solve and the loading before it were 0 in timings.yaml.
TEST_F(MultiLogCalibration, EachLogRecordsItsTimes) {
  for (const LogCalibration& log : result_->logs) {
    const OfflineCalibrationResult& own = log.own;
    EXPECT_GT(own.seconds_loading, 0.0) << log.name;
    EXPECT_GT(own.seconds_initialization, 0.0) << log.name;
    EXPECT_GT(own.batch.seconds_solver, 0.0) << log.name;
    EXPECT_LE(own.batch.seconds_solver, own.seconds_solve) << log.name;
    EXPECT_NEAR(own.seconds_loading + own.seconds_initialization + own.seconds_solve,
                own.seconds_total, 1e-9)
        << log.name;
  }
}

// A log named with a comma and a quote (its directory's name) stays one quoted field of
// repeatability.csv, as text is in fleet.csv.
TEST_F(MultiLogCalibration, QuotesLogNamesInTheCsv) {
  MultiLogCalibrationResult renamed = *result_;
  renamed.logs[0].name = "day 1, \"wet\"";
  std::istringstream csv(RepeatabilityCsv(renamed));
  std::string line;
  std::getline(csv, line);
  int rows = 0;
  while (std::getline(csv, line)) {
    if (line.find("wet") == std::string::npos) continue;
    ++rows;
    EXPECT_THAT(line, ::testing::HasSubstr(",\"day 1, \"\"wet\"\"\","));
    EXPECT_EQ(std::count(line.begin(), line.end(), ','), 10) << line;  // 9 separators, 1 inside
  }
  EXPECT_GT(rows, 0);
  EXPECT_EQ(CsvText("a,\"b\""), "\"a,\"\"b\"\"\"");
}

// The link to a log's own report holds its name percent-encoded: a '#' would start a
// fragment, a '%' an escape.
TEST_F(MultiLogCalibration, LinksToLogsWithAnyName) {
  MultiLogCalibrationResult renamed = *result_;
  renamed.logs[0].name = "run #2 at 50% <o'clock>";
  const std::string html = MultiLogReportHtml(renamed);
  EXPECT_THAT(html,
              ::testing::HasSubstr(
                  "<a href='logs/run%20%232%20at%2050%25%20%3Co%27clock%3E/own/report.html'>"));
  EXPECT_THAT(html, ::testing::HasSubstr("<li>run #2 at 50% &lt;o&#39;clock&gt; ("));
}

// The course's example: a tyre whose pressure changed between two days.
TEST(MultiLogRepeatability, FindsTheChangedTyre) {
  std::vector<std::unique_ptr<test::SimulatedUrbanDataset>> logs;
  logs.push_back(Log(31));
  logs.push_back(Log(32));
  logs.push_back(Log(34, 0.4));
  std::vector<io::Dataset> datasets = Read(logs);
  const MultiLogCalibrationResult result = CalibrateDatasets(datasets, ImuWheelGnssProblem());
  std::cout << FormatMultiLogSummary(result);
  for (const BlockRepeatability& r : result.repeatability) {
    if (r.agreement.id != sensors::CalibrationBlockId::kWheelRadiusRight) continue;
    EXPECT_FALSE(r.agree);
    EXPECT_LT(r.agreement.p_value, 1e-6);
    EXPECT_EQ(r.agreement.log_b, 2u);
    const double change_pct =
        100.0 * r.agreement.difference /
        result.logs[r.agreement.log_a].own.posterior.solved.wheel_radius_right_m;
    EXPECT_NEAR(change_pct, 0.4, 0.05);
    EXPECT_THAT(r.finding, ::testing::HasSubstr("tyre pressure or wear?"));
    EXPECT_THAT(r.finding, ::testing::HasSubstr(result.logs[2].name));
  }
  EXPECT_THAT(result.warnings,
              ::testing::Contains(::testing::HasSubstr("calibrate those logs apart")));
  // The changed tyre's log solved at the shared radius, as its trajectory is written: its
  // fixed-block test (Eq. C7) says its data would move that radius. Each log's warnings there
  // are the result's, named by the log (they were dropped before).
  for (const LogCalibration& log : result.logs) {
    const std::string prefix = "log " + log.name + " at the shared calibration: ";
    EXPECT_EQ(std::count_if(result.warnings.begin(), result.warnings.end(),
                            [&](const std::string& w) { return w.rfind(prefix, 0) == 0; }),
              static_cast<std::ptrdiff_t>(log.at_shared.warnings.size()))
        << log.name;
  }
  EXPECT_THAT(result.warnings,
              ::testing::Contains(::testing::AllOf(
                  ::testing::StartsWith("log " + result.logs[2].name +
                                        " at the shared calibration: right rear wheel radius"),
                  ::testing::HasSubstr("is fixed, but the data would move it"),
                  ::testing::EndsWith("this log's data disagree with the shared value"))));
}

// With each log's truth (simulated logs), each log's own result carries its Cramer-Rao
// bound; one setter for every log, or a count that does not match, is refused.
TEST(MultiLogRepeatability, BoundsEachLogAgainstItsOwnTruth) {
  std::vector<std::unique_ptr<test::SimulatedUrbanDataset>> logs;
  logs.push_back(Log(31));
  logs.push_back(Log(32));
  std::vector<io::Dataset> datasets = Read(logs);
  MultiLogCalibrationOptions options;
  options.set_to_truth = {evaluation::TruthSetter(datasets[0])};
  EXPECT_THROW(CalibrateDatasets(datasets, ImuWheelGnssProblem(), options), Error);
  MultiLogCalibrationOptions shared;
  shared.calibration.set_to_truth = evaluation::TruthSetter(datasets[0]);
  EXPECT_THROW(CalibrateDatasets(datasets, ImuWheelGnssProblem(), shared), Error);

  options.set_to_truth.push_back(evaluation::TruthSetter(datasets[1]));
  const MultiLogCalibrationResult result =
      CalibrateDatasets(datasets, ImuWheelGnssProblem(), options);
  for (const LogCalibration& log : result.logs) {
    ASSERT_TRUE(log.own.bound) << log.name;
    EXPECT_EQ(log.own.bound->matrix.rows(), log.own.posterior.covariance.matrix.rows());
    EXPECT_FALSE(log.at_shared.bound) << log.name;  // nothing estimated there
  }
}

// One radius for both wheels: the shared calibration gives the right wheel the fused estimate
// with its sigma, not the first log's nominal right radius without one.
TEST(MultiLogRepeatability, GivesASharedRadiusToBothWheels) {
  std::vector<std::unique_ptr<test::SimulatedUrbanDataset>> logs;
  logs.push_back(Log(31));
  logs.push_back(Log(32));
  std::vector<io::Dataset> datasets = Read(logs);
  io::Problem problem = ImuWheelGnssProblem();
  problem.calibration.wheel_radius_shared = true;
  const MultiLogCalibrationResult result = CalibrateDatasets(datasets, problem);
  const io::CalibrationFile& shared = result.calibration;
  ASSERT_TRUE(shared.uncertainty.wheel_radius_left_m.sigma.has_value());
  EXPECT_EQ(shared.value.wheel_radius_right_m, shared.value.wheel_radius_left_m);
  EXPECT_EQ(shared.uncertainty.wheel_radius_right_m.sigma,
            shared.uncertainty.wheel_radius_left_m.sigma);
  EXPECT_EQ(shared.uncertainty.wheel_radius_right_m.observable,
            shared.uncertainty.wheel_radius_left_m.observable);
}

TEST(MultiLogRepeatability, RefusesFewerThanTwoLogs) {
  EXPECT_THROW(CalibrateDatasets({}, ImuWheelGnssProblem()), Error);
}

// Logs are named after their directories (a trailing slash ignored), made unique: a log's
// position, then further numbers while the name is taken ("day_3", "day", "day" gives day_3,
// day, day_4).
TEST(MultiLogRepeatability, NamesEveryLogApart) {
  std::vector<io::Dataset> datasets;
  for (uint64_t seed : {31, 32, 33}) datasets.push_back(io::ReadDataset(Log(seed)->directory));
  datasets[0].directory += "/../day_3/";  // read already: the name is all that changes
  datasets[1].directory += "/../a/day";
  datasets[2].directory += "/../b/day";
  const MultiLogCalibrationResult result = CalibrateDatasets(datasets, ImuWheelGnssProblem());
  ASSERT_EQ(result.logs.size(), 3u);
  EXPECT_EQ(result.logs[0].name, "day_3");
  EXPECT_EQ(result.logs[1].name, "day");
  EXPECT_EQ(result.logs[2].name, "day_4");
}

// The same log twice would halve its variance without new data.
TEST(MultiLogRepeatability, RefusesALogGivenTwice) {
  const std::unique_ptr<test::SimulatedUrbanDataset> log = Log(31);
  io::Dataset again = io::ReadDataset(log->directory);
  again.directory = log->directory + "/.";
  try {
    CalibrateDatasets({io::ReadDataset(log->directory), again}, ImuWheelGnssProblem());
    ADD_FAILURE() << "a log given twice was calibrated";
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("is given twice"));
  }
}

}  // namespace
}  // namespace pipeline
}  // namespace autocal
